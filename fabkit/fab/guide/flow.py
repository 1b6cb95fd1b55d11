"""Text that flows over as many pages as it needs (pure data, nothing drawn).

A page of the guide sets its lists (stacks, hardware, how the pages join, every port) as
blocks: a heading and lines in one style, in one or more columns. :func:`flow` cuts blocks
into pages of a given room, repeating a split block's heading with "(continued)", so that no
line is ever set below a page's bottom margin and no text is set smaller than
:data:`MIN_PT`. Every line is drawn as a text of its own at a fixed pitch
(:func:`block_height` is exactly what :mod:`.pages` draws), so the layout decided here is the
layout drawn, and page numbers are known before a page is drawn.
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, replace

__all__ = ["Block", "STYLES", "MIN_PT", "flow", "block_height", "wrap_row", "chars_per_line",
           "column_lines", "PAGE_WIDTH_PT", "BLOCK_GAP_PT"]

#: No text of a guide page is set smaller than this (points).
MIN_PT = 7.0
#: Width of a page's text column (the A4 page less its margins, 7.17 in), points.
PAGE_WIDTH_PT = 7.17 * 72.0
#: Space after a block (points).
BLOCK_GAP_PT = 6.0
#: Space between columns (points).
COLUMN_GAP_PT = 12.0

#: Style -> (font size in points, line pitch as a multiple of the size, mean advance of a
#: character as a multiple of the size, monospaced). DejaVu Sans Mono advances 0.602 em; the
#: running text's 0.575 em is DejaVu Sans' widest lines of the guide, measured.
STYLES = {
    "head": (9.0, 1.5, 0.62, False),
    "body": (8.0, 1.4, 0.575, False),
    "mono": (7.5, 1.3, 0.602, True),
}


@dataclass(frozen=True)
class Block:
    """A heading and rows of text in one style.

    Attributes
    ----------
    head : str or None
        Set in bold above the rows (repeated, "(continued)", where the block is split).
    rows : tuple of str
        Rows in order; a row too long for its column is wrapped (continuation lines indented)
        and is never split between columns or pages.
    style : str
        ``"mono"`` or ``"body"`` (:data:`STYLES`).
    columns : int
        Rows fill the first column top down, then the next.
    continued : bool
        This block is the rest of one begun on an earlier page.
    """

    head: str | None
    rows: tuple
    style: str = "mono"
    columns: int = 1
    continued: bool = False

    @property
    def title(self) -> str | None:
        if self.head is None:
            return None
        return f"{self.head} (continued)" if self.continued else self.head


def chars_per_line(style: str, columns: int = 1) -> int:
    """Characters of ``style`` that fit in one of ``columns`` columns of a page."""
    size, _, em, _ = STYLES[style]
    width = (PAGE_WIDTH_PT - (columns - 1) * COLUMN_GAP_PT) / columns
    return max(int(width / (em * size)) - 1, 8)


def wrap_row(row: str, style: str, columns: int = 1) -> list:
    """The lines a row is set in (a monospaced row's continuation lines indented by four
    spaces); an empty row is one empty line."""
    width = chars_per_line(style, columns)
    if len(row) <= width:
        return [row]
    indent = "    " if STYLES[style][3] else ""
    return textwrap.wrap(row, width, subsequent_indent=indent, break_on_hyphens=False) or [""]


def _pitch(style: str) -> float:
    size, pitch, _, _ = STYLES[style]
    return size * pitch


def _head_pt(block: Block) -> float:
    return _pitch("head") if block.head is not None else 0.0


def column_lines(block: Block) -> list:
    """Lines of each column (rows kept whole, columns filled to near-equal height)."""
    rows = [wrap_row(r, block.style, block.columns) for r in block.rows]
    total = sum(len(r) for r in rows)
    per = math.ceil(total / block.columns) if block.columns > 1 else total
    cols, cur = [], []
    for r in rows:
        if cur and len(cur) + len(r) > per and len(cols) < block.columns - 1:
            cols.append(cur)
            cur = []
        cur = cur + r
    cols.append(cur)
    return cols


def block_height(block: Block) -> float:
    """Height of a block as drawn (points): heading, the tallest column, the gap after it."""
    lines = max((len(c) for c in column_lines(block)), default=0)
    return _head_pt(block) + lines * _pitch(block.style) + BLOCK_GAP_PT


def _split(block: Block, room: float):
    """The head of ``block`` that fits in ``room`` points (whole rows, filling columns), and
    the rest; (None, block) when not even one row fits."""
    pitch = _pitch(block.style)
    lines_fit = int((room - _head_pt(block) - BLOCK_GAP_PT) // pitch)
    if lines_fit < 1:
        return None, block
    wrapped = [wrap_row(r, block.style, block.columns) for r in block.rows]
    taken, cols, used = 0, 0, 0
    for rows in wrapped:
        if used + len(rows) > lines_fit:
            cols += 1
            used = 0
            if cols >= block.columns or len(rows) > lines_fit:
                break
        used += len(rows)
        taken += 1
    # columns are drawn balanced, rows whole: make sure what is kept fits as drawn
    while taken > 0 and block_height(replace(block, rows=tuple(block.rows[:taken]))) > room:
        taken -= 1
    if taken == 0:
        return None, block
    head = replace(block, rows=tuple(block.rows[:taken]))
    rest = replace(block, rows=tuple(block.rows[taken:]), continued=True)
    return head, rest


def flow(blocks, first_room: float, next_room: float) -> list:
    """Cut blocks into pages.

    Parameters
    ----------
    blocks : list of Block
    first_room : float
        Height (points) for text on the first page.
    next_room : float
        Height on each page that follows.

    Returns
    -------
    list of list of Block
        The blocks of each page (at least one page, possibly empty).
    """
    pages, cur, room = [], [], float(first_room)
    queue = [b for b in blocks if b.rows or b.head is not None]
    while queue:
        block = queue.pop(0)
        if block_height(block) <= room:
            cur.append(block)
            room -= block_height(block)
            continue
        head, rest = _split(block, room)
        if head is None and not cur and room >= next_room:
            # one row taller than a whole page: set it anyway (never met in a guide)
            head, rest = replace(block, rows=block.rows[:1]), replace(
                block, rows=block.rows[1:], continued=True)
        if head is not None:
            cur.append(head)
        pages.append(cur)
        cur, room = [], float(next_room)
        if rest.rows:
            queue.insert(0, rest)
    pages.append(cur)
    if len(pages) > 1 and not pages[-1]:
        pages.pop()
    return pages
