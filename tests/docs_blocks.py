"""The fenced blocks of README.md and docs/*.md, with the marks that say how the docs test runs them.

Every fence names its language. ``sh`` and ``python`` blocks are run as written, each in a fresh
empty folder (shell blocks with ``bash -e``, the checkout's ``.venv/bin`` first on PATH, so
``fabkit`` is the checkout's; python blocks with the same interpreter as the tests). ``toml``
blocks must parse; ``text`` blocks (output, usage synopses) are not run.

A mark is an HTML comment on the line just before the fence, ``<!-- docs: WORD ... -->``, words
separated by `` ; ``:

``slow``
    the block takes more than a few seconds: it runs in the slow suite only.
``continues``
    the block uses files or names of the previous block of the same page: it runs after it, in
    the same folder (consecutive python blocks in the same process).
``exits N``
    the shell block is an example of a failure: it must exit with status N.
``checkout``
    the block is written for a clone of the repository: its folder holds a copy of the
    checkout's ``templates/`` and ``tests/data/``.
``cluster``
    the block needs machines running a dask scheduler and workers: not run (tests/test_sweep.py
    runs the same commands on a local cluster).
``not run: REASON``
    not run, for the reason given (e.g. it installs into the home folder); the reason runs to
    the end of the mark, so it comes last.
``output of: COMMAND``
    on a ``text`` block: what COMMAND prints (a first line ``$ COMMAND`` shows it to the reader).
    The test runs COMMAND like a shell block (``exits N`` and ``continues`` apply) and finds
    every other line of the block, in order, among the lines it printed on stdout and stderr
    (durations such as ``2.46 s`` excepted: they are the machine's), so the numbers quoted
    cannot drift from the code's. Words are separated by ``;``, so COMMAND holds none.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

RUN_LANGUAGES = {"sh", "python"}
DATA_LANGUAGES = {"toml", "text"}
MARK = re.compile(r"^<!--\s*docs:\s*(.*?)\s*-->\s*$")
FENCE = re.compile(r"^```(\S*)\s*$")
NOT_RUN = ("cluster", "not run")


@dataclass
class Block:
    """One fenced block of a page: where it is, its language, its marks and its text."""

    page: Path
    line: int                    # line of the opening fence, 1-based
    language: str
    code: str
    marks: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        page = self.page.relative_to(ROOT) if self.page.is_relative_to(ROOT) else self.page
        return f"{page}:{self.line}"

    def has(self, word: str) -> bool:
        return any(m == word or m.startswith(word + " ") or m.startswith(word + ":")
                   for m in self.marks)

    @property
    def runs(self) -> bool:
        code = self.language in RUN_LANGUAGES or self.output_of is not None
        return code and not any(self.has(w) for w in NOT_RUN)

    @property
    def quoted_lines(self) -> list[str]:
        """An ``output of`` block's lines as compared: without the ``$ COMMAND`` line."""
        return comparable_lines("\n".join(line for line in self.code.splitlines()
                                           if not line.startswith("$ ")))

    @property
    def slow(self) -> bool:
        return self.has("slow")

    @property
    def output_of(self) -> str | None:
        for m in self.marks:
            if m.startswith("output of:"):
                return m[len("output of:"):].strip()
        return None

    @property
    def exit_status(self) -> int:
        for m in self.marks:
            if m.startswith("exits "):
                return int(m.split()[1])
        return 0


def parse_marks(line: str) -> list[str]:
    """The words of a ``<!-- docs: ... -->`` line (empty when the line is not a mark)."""
    m = MARK.match(line)
    if not m:
        return []
    words = []
    for part in m.group(1).split(";"):
        if words and words[-1].startswith("not run:"):
            words[-1] += ";" + part      # a reason runs to the end of the mark
        elif part.strip():
            words.append(part.strip())
    return words


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of one markdown page, in order."""
    lines = page.read_text(encoding="utf-8").splitlines()
    found, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        end = i + 1
        while end < len(lines) and not lines[end].startswith("```"):
            end += 1
        marks = parse_marks(lines[i - 1]) if i else []
        found.append(Block(page, i + 1, m.group(1), "\n".join(lines[i + 1:end]) + "\n", marks))
        i = end + 1
    return found


DURATION = re.compile(r"\d+(\.\d+)? ?s\b")


def comparable_lines(text: str) -> list[str]:
    """Lines of printed output as the docs test compares them: durations masked, right-stripped."""
    return [DURATION.sub("<time>", line).rstrip() for line in text.splitlines() if line.strip()]


def all_blocks() -> list[Block]:
    return [b for page in PAGES for b in blocks(page)]


def chains(page_blocks: list[Block]) -> list[list[Block]]:
    """Blocks grouped into runs: a ``continues`` block joins the run of the block before it."""
    runs: list[list[Block]] = []
    for b in page_blocks:
        if b.has("continues") and runs:
            runs[-1].append(b)
        else:
            runs.append([b])
    return runs


def runnable_chains() -> list[list[Block]]:
    """Every run of blocks the docs test executes (a run is slow when any block in it is)."""
    out = []
    for page in PAGES:
        for run in chains(blocks(page)):
            run = [b for b in run if b.runs]
            if run:
                out.append(run)
    return out


KNOWN_WORDS = ("slow", "continues", "checkout", "cluster")
KNOWN_PREFIXES = ("exits ", "not run:", "output of:")


def problems(page_blocks: list[Block]) -> list[str]:
    """What is wrong with the blocks of a page: a fence without a known language, a shell or
    Python block neither run nor given a reason, an unknown mark, a mark where it means nothing."""
    found = []
    for i, b in enumerate(page_blocks):
        if b.language not in RUN_LANGUAGES | DATA_LANGUAGES:
            found.append(f"{b.name}: fence without a known language ({b.language!r}); "
                         f"use one of {sorted(RUN_LANGUAGES | DATA_LANGUAGES)}")
        elif b.language in RUN_LANGUAGES and not b.runs:
            if not any(m == "cluster" or (m.startswith("not run:") and m[8:].strip())
                       for m in b.marks):
                found.append(f"{b.name}: not run and no reason given")
        for m in b.marks:
            if m not in KNOWN_WORDS and not m.startswith(KNOWN_PREFIXES):
                found.append(f"{b.name}: unknown mark {m!r} (see tests/docs_blocks.py)")
            elif m.startswith("exits ") and not m[6:].strip().isdigit():
                found.append(f"{b.name}: {m!r}: the exit status is a number")
        if b.exit_status and b.language != "sh" and not b.output_of:
            found.append(f"{b.name}: 'exits N' is for shell blocks and quoted output")
        if b.output_of is not None and (b.language != "text" or not b.output_of):
            found.append(f"{b.name}: 'output of: COMMAND' is for text blocks, with a command")
        shown = [re.sub(r"\s+#.*$", "", line[2:]).strip() for line in b.code.splitlines()
                 if line.startswith("$ ")]
        if b.output_of and shown and shown != [b.output_of]:
            found.append(f"{b.name}: shows `$ {shown[0]}`, runs `{b.output_of}`")
        if b.has("continues") and i == 0:
            found.append(f"{b.name}: 'continues' on the first block of the page")
    return found


def missing_line(block: Block, printed: str) -> str | None:
    """The first line ``block`` quotes that is not in ``printed`` (in order), or None."""
    lines = comparable_lines(printed)
    at = 0
    for line in block.quoted_lines:
        if line not in lines[at:]:
            return line
        at = lines.index(line, at) + 1
    return None
