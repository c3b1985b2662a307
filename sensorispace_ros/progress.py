"""Progress display on stderr: stage, fraction, elapsed time, ETA.

On a terminal one line is rewritten in place; otherwise (CI logs, pipes)
plain lines are printed at most every ``interval_s`` seconds, plus one line
when each stage ends, so logs stay short and readable.

Core functions take a plain callable ``progress(done, total=None)``: an
object of this class is such a callable (``done`` may also be a fraction in
[0, 1] when ``total`` is None), and ``None`` means "no display".
"""
from __future__ import annotations

import sys
import time
from contextlib import contextmanager
from typing import Callable, Iterator, TextIO


def format_seconds(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.1f}s"
    minutes, secs = divmod(int(round(seconds)), 60)
    if minutes < 60:
        return f"{minutes}m{secs:02d}s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours}h{minutes:02d}m"


class Progress:
    """Stage-by-stage progress of one run.

    >>> progress = Progress()
    >>> with progress.stage("hausdorff", total=649):
    ...     for i in range(649):
    ...         progress(i + 1)
    """

    def __init__(self, stream: TextIO | None = None, interactive: bool | None = None,
                 interval_s: float = 10.0, clock: Callable[[], float] = time.monotonic,
                 enabled: bool = True):
        self.stream = sys.stderr if stream is None else stream
        if interactive is None:
            isatty = getattr(self.stream, "isatty", None)
            interactive = bool(isatty and isatty())
        self.interactive = interactive
        self.interval_s = float(interval_s)
        self.clock = clock
        self.enabled = enabled
        self.stage_name: str | None = None
        self.total: float | None = None
        self.fraction = 0.0
        self._stage_start = 0.0
        self._last_line = -float("inf")
        self._line_width = 0
        self.durations: dict[str, float] = {}

    # -- stages --------------------------------------------------------------

    @contextmanager
    def stage(self, name: str, total: float | None = None) -> Iterator["Progress"]:
        """Time a stage; ``self.durations[name]`` holds its wall time afterwards."""
        outer = (self.stage_name, self.total, self.fraction, self._stage_start)
        self.stage_name, self.total, self.fraction = name, total, 0.0
        self._stage_start = self.clock()
        # Plain logs get a line only for stages that last longer than interval_s.
        self._last_line = self._stage_start
        if self.interactive:
            self._render(force=True)
        try:
            yield self
        finally:
            elapsed = self.clock() - self._stage_start
            self.durations[name] = self.durations.get(name, 0.0) + elapsed
            self._finish_line(f"[{name}] done in {format_seconds(elapsed)}")
            self.stage_name, self.total, self.fraction, self._stage_start = outer
            self._last_line = self.clock()

    def __call__(self, done: float, total: float | None = None) -> None:
        self.update(done, total)

    def update(self, done: float, total: float | None = None) -> None:
        """Report ``done`` units of ``total`` (or of the stage's total), or a fraction."""
        if total is not None:
            self.total = total
        total = self.total
        if total:
            fraction = float(done) / float(total)
        else:
            fraction = float(done)
        self.fraction = min(max(fraction, 0.0), 1.0)
        self._render()

    def message(self, text: str) -> None:
        """A line of its own (e.g. a warning) that does not break the display."""
        self._finish_line(text)

    # -- output --------------------------------------------------------------

    def status(self) -> str:
        elapsed = self.clock() - self._stage_start
        parts = [f"[{self.stage_name}]", f"{100.0 * self.fraction:5.1f}%",
                 f"elapsed {format_seconds(elapsed)}"]
        if 0.0 < self.fraction < 1.0:
            remaining = elapsed * (1.0 - self.fraction) / self.fraction
            parts.append(f"ETA {format_seconds(remaining)}")
        return " ".join(parts)

    def _render(self, force: bool = False) -> None:
        if not self.enabled or self.stage_name is None:
            return
        now = self.clock()
        if self.interactive:
            # Redrawing a terminal line costs little, but not 10^5 times.
            if not force and now - self._last_line < 0.1:
                return
            line = self.status()
            pad = max(self._line_width - len(line), 0)
            self.stream.write("\r" + line + " " * pad)
            self._line_width = len(line)
            self.stream.flush()
        else:
            # 100 % is said by the stage's closing line.
            if not force and (now - self._last_line < self.interval_s or self.fraction >= 1.0):
                return
            self.stream.write(self.status() + "\n")
            self.stream.flush()
        self._last_line = now

    def _finish_line(self, text: str) -> None:
        if not self.enabled:
            return
        if self.interactive and self._line_width:
            self.stream.write("\r" + " " * self._line_width + "\r")
            self._line_width = 0
        self.stream.write(text + "\n")
        self.stream.flush()
