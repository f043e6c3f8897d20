"""Tables that never lose a figure, at any terminal width.

rich shrinks a table that is wider than the terminal by cutting cells to `13.…` or dropping
whole columns, silently. A `Grid` is printed instead in the first of three layouts that fits:

1. a table with one-line headers ("mass kg");
2. the same table with the unit under the name, two header lines, and no padding at its edges
   (narrower: the period table fits 80 columns);
3. one block per row: a heading (the row's first cell), then `name value unit` items packed
   onto lines no wider than the terminal, never breaking inside an item.

Cells are plain text (or rich Text for colour): a path or a label is never read as markup.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field

from rich import box
from rich.console import Console
from rich.table import Table
from rich.text import Text

# Width assumed when stdout is not a terminal and COLUMNS is unset: rich would take 80, which
# pushes a file or a pipe into the block layout for no reason.
PIPE_WIDTH = 120
_NATURAL = 100_000  # measuring width: wide enough that no column is shrunk


@dataclass(frozen=True)
class Column:
    """name: what the column holds; unit: appended to the name (and to each value in blocks);
    left: left-justified (text) rather than right (figures); blank: what an empty cell means,
    said in the block layout (where an empty item would read as missing data)."""

    name: str
    unit: str = ""
    left: bool = False
    blank: str = "–"


@dataclass
class Grid:
    """A table: title, columns, rows of cells (str or rich Text), caption. heading: format of
    a block's heading in the block layout, from the row's first cell (e.g. "period {}")."""

    title: str
    columns: list[Column]
    rows: list[list[str | Text]] = field(default_factory=list)
    caption: str = ""
    heading: str = "{}"


def console(stderr: bool = False) -> Console:
    """A console for tables: the terminal's width; in a pipe COLUMNS, else PIPE_WIDTH."""
    stream = sys.stderr if stderr else sys.stdout
    piped = not stream.isatty() and not os.environ.get("COLUMNS", "").isdigit()
    return Console(highlight=False, stderr=stderr, width=PIPE_WIDTH if piped else None)


def _text(cell: str | Text) -> Text:
    return cell if isinstance(cell, Text) else Text(cell)


def table(grid: Grid, compact: bool = False) -> Table:
    """The grid as a rich Table; no cell wraps (the caller checks that it fits). compact: units
    under the names and no padding at the edges. The caption is left out: rich would widen the
    table to it (`show` prints it below, wrapped)."""
    result = Table(title=grid.title, box=box.SIMPLE_HEAD, pad_edge=not compact)
    for column in grid.columns:
        joint = "\n" if compact else " "
        header = f"{column.name}{joint}{column.unit}" if column.unit else column.name
        result.add_column(header, justify="left" if column.left else "right", no_wrap=True)
    for row in grid.rows:
        result.add_row(*(_text(cell) for cell in row))
    return result


def natural_width(console: Console, renderable: Table) -> int:
    """Width the table takes when nothing is shrunk."""
    return renderable.__rich_measure__(console, console.options.update_width(_NATURAL)).maximum


def blocks(grid: Grid, width: int) -> list[Text]:
    """The block layout: the title, then per row a heading line and its items packed into lines
    <= width (the caption is left to the caller: it is prose, wrapped like prose)."""
    lines = [Text(grid.title, style="italic")] if grid.title else []
    indent, gap = "  ", "   "
    for row in grid.rows:
        lines.append(Text(grid.heading.format(_text(row[0]).plain), style="bold"))
        line = Text(indent)
        for column, cell in zip(grid.columns[1:], row[1:], strict=True):
            value = _text(cell) if _text(cell).plain else Text(column.blank)
            item = Text(f"{column.name} ", style="dim") + value
            if column.unit:
                item += Text(f" {column.unit}")
            if line.plain.strip() and len(line) + len(gap) + len(item) > width:
                lines.append(line)
                line = Text(indent)
            line += Text(gap) + item if line.plain.strip() else item
        lines.append(line)
    return lines


def show(console: Console, grid: Grid) -> None:
    """Print the grid in the first layout that fits the console's width."""
    for compact in (False, True):
        candidate = table(grid, compact)
        if natural_width(console, candidate) <= console.width:
            console.print(candidate)
            break
    else:
        for line in blocks(grid, console.width):
            # soft_wrap: an item wider than the terminal (a long label) is left whole for the
            # terminal to wrap, not cut by rich.
            console.print(line, soft_wrap=True)
    if grid.caption:
        console.print(Text(grid.caption, style="dim"))
