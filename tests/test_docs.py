"""The documentation says what the software is: a short README whose first
commands are the two scripts, an architecture tree that lists exactly the
package's modules, and no development-history wording (work sessions, issue
numbers) anywhere but the dated benchmark journal."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

from shared import REPO as ROOT
README = ROOT / "README.md"
PACKAGE = "sensorispace_ros"
JOURNAL = "bench/JOURNAL.md"      # the one place allowed to keep history wording
README_MAX_LINES = 250

# Development history: numbered work sessions ("session N", "sessions N-M",
# "session-N") and issue numbers ("issue #N", "issue N", "issueN-...",
# "#N bench", "#N's bar", "(#N)"), N a number. Colours ("#2166ac"), shell
# comments and `start_new_session` do not match.
HISTORY_PATTERNS = [
    re.compile(r"\bsessions?[ -]\d", re.IGNORECASE),
    re.compile(r"\bissues?[\s_-]*#?\s*\d", re.IGNORECASE),
    re.compile(r"(?<![\w#&])#\d+(?:'s)?\s+(?:bench|bar|target|marked|parity|notes|measured)\b",
               re.IGNORECASE),
    re.compile(r"\((?:see\s+)?#\d+\)"),
]


def tracked_files() -> list[str]:
    """``git ls-files`` of the checkout; a tree without git is walked instead
    (every file but caches and the virtual environment)."""
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, check=True,
                             capture_output=True).stdout
    except (OSError, subprocess.CalledProcessError):
        skip = {".git", ".venv", "__pycache__", ".pytest_cache", "results", "bags"}
        return sorted(str(p.relative_to(ROOT)) for p in ROOT.rglob("*")
                      if p.is_file() and not skip & set(p.relative_to(ROOT).parts))
    return sorted(name for name in out.decode().split("\0") if name and (ROOT / name).is_file())


def fenced_blocks(text: str) -> list[tuple[int, list[str]]]:
    """Fenced code blocks as (line number of the opening fence, lines inside)."""
    blocks, inside, start, lines = [], False, 0, []
    for number, line in enumerate(text.splitlines()):
        if line.startswith("```"):
            if inside:
                blocks.append((start, lines))
            inside, start, lines = not inside, number, []
        elif inside:
            lines.append(line)
    return blocks


def history_hits(name: str, text: str) -> list[str]:
    return [f"{name}:{number}: {line.strip()}"
            for number, line in enumerate(text.splitlines(), 1)
            if any(pattern.search(line) for pattern in HISTORY_PATTERNS)]


def tree_entries(lines: list[str], root: str = PACKAGE) -> set[str]:
    """Paths listed under ``<root>/`` in an indented tree (two spaces a level,
    one entry a line, then at least two spaces and a comment); directories end
    with a slash. Lines at depth 0 other than the root end its subtree."""
    entries: set[str] = set()
    stack: list[str] = []
    in_root = False
    for line in lines:
        if not line.strip():
            continue
        indent = len(line) - len(line.lstrip(" "))
        assert indent % 2 == 0, f"tree line not indented by two spaces a level: {line!r}"
        depth, name = indent // 2, line.split()[0]
        if depth == 0:
            in_root = name == f"{root}/"
            stack = [root] if in_root else []
            continue
        if not in_root:
            continue
        assert depth <= len(stack), f"tree line deeper than its parent: {line!r}"
        del stack[depth:]
        path = "/".join(stack + [name.rstrip("/")])
        entries.add(path + ("/" if name.endswith("/") else ""))
        if name.endswith("/"):
            stack.append(name.rstrip("/"))
    return entries


def readme_tree() -> list[str]:
    text = README.read_text()
    heading = text.index("\n## Architecture\n")
    for start, lines in fenced_blocks(text):
        if start > text[:heading].count("\n"):
            return lines
    raise AssertionError("README has no code block after '## Architecture'")


def test_readme_is_short_and_opens_with_the_two_commands():
    text = README.read_text()
    lines = text.splitlines()
    assert len(lines) <= README_MAX_LINES, f"README has {len(lines)} lines"
    assert lines[0].startswith("# ")
    first_text = next(line for line in lines[1:] if line.strip())
    assert first_text.startswith("```"), "the first thing under the title is not a code block"
    _, first = fenced_blocks(text)[0]
    commands = [line.split("#", 1)[0].strip() for line in first]
    assert commands == ["bash scripts/main.sh", "bash scripts/test.sh"], first
    assert all("#" in line and line.split("#", 1)[1].strip() for line in first), \
        "each of the two commands has a one-line comment"


def test_readme_tree_lists_every_module_and_nothing_else():
    modules = {name for name in tracked_files()
               if name.startswith(f"{PACKAGE}/") and not name.endswith("/__init__.py")}
    directories = {str(Path(name).parent) + "/" for name in tracked_files()
                   if name.startswith(f"{PACKAGE}/") and "/" in name[len(PACKAGE) + 1:]}
    listed = tree_entries(readme_tree())
    listed_files = {entry for entry in listed if not entry.endswith("/")}
    assert sorted(modules - listed_files) == [], "modules missing from the README tree"
    assert sorted(listed_files - modules) == [], "README tree lists files that do not exist"
    assert sorted({e for e in listed if e.endswith("/")} - directories) == [], \
        "README tree lists directories that do not exist"


def test_tree_parser_sees_files_and_directories():
    lines = ["pkg/", "  a.py         what a is", "  sub/         a directory",
             "    b.py       in sub", "  c.py", "other/        not the package",
             "  d.py"]
    assert tree_entries(lines, root="pkg") == {"pkg/a.py", "pkg/sub/", "pkg/sub/b.py",
                                               "pkg/c.py"}


def test_no_development_history_outside_the_journal():
    hits = []
    for name in tracked_files():
        if name == JOURNAL:
            continue
        try:
            text = (ROOT / name).read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue                                  # binary: images, bags
        hits.extend(history_hits(name, text))
    assert hits == [], "development-history wording:\n" + "\n".join(hits)


# Built from pieces (split inside each match) so that this file itself holds no such wording.
PLANTED = ["measured in sess" + "ion 12", "since sess" + "ions 1-7", "the second sess" + "ion-10 bench",
           "see iss" + "ue #4", "(iss" + "ue 7)", "patches/iss" + "ue6-equality.patch",
           "#" + "4 bench: 1.9x", "the #" + "6's bar", "a fix (#" + "4)", "Iss" + "ue #2: grid"]
LEGITIMATE = ['color="#2166ac"', "start_new_session=True", "/session/config topic",
              "# 3 lights in view", "SESSION_CONFIG_TOPIC", "an issue with the lease",
              "step #1 of the loop", "issues found by the fuzzer"]


@pytest.mark.parametrize("line", PLANTED)
def test_history_search_finds_a_planted_line(line):
    assert history_hits("planted.py", f"x = 1\n{line}\n") == [f"planted.py:2: {line}"]


@pytest.mark.parametrize("line", LEGITIMATE)
def test_history_search_leaves_legitimate_text_alone(line):
    assert history_hits("fine.py", line) == []
