"""Wall time of the named stages of a run, shown on a progress display."""
from __future__ import annotations

import time
from contextlib import contextmanager, nullcontext
from typing import Callable, Iterator


@contextmanager
def timed_stage(progress, name: str, timings: dict,
                total: float | None = None) -> Iterator[Callable]:
    """Add the wall time of the block to ``timings[name]``; show the stage on
    ``progress`` when it has a ``stage`` method (``progress.Progress``)."""
    display = progress.stage(name, total) if hasattr(progress, "stage") else nullcontext()
    start = time.perf_counter()
    with display:
        yield progress
    timings[name] = timings.get(name, 0.0) + time.perf_counter() - start
