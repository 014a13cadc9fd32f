"""Markdown tables for the reports the package writes (table1.md, Table II, placements).

Not tabulate or pandas' to_markdown: neither is a dependency, and both pad each cell to its
column's width, so every stored report would change byte for byte."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

__all__ = ["markdown_row", "markdown_table"]


def markdown_row(cells: Iterable[object]) -> str:
    """One table row: `| a | b |`, each cell as str() gives it (an empty cell stays empty)."""
    return "| " + " | ".join(str(c) for c in cells) + " |"


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[object]] = (), *,
                   align: Sequence[str] | None = None) -> list[str]:
    """The lines of a table: the header, the alignment row (`---` a column unless `align`
    gives each column's, e.g. `---:` for right-aligned), then one line a row."""
    align = ["---"] * len(header) if align is None else list(align)
    if len(align) != len(header):
        raise ValueError(f"{len(align)} alignments for {len(header)} columns")
    return [markdown_row(header), "|" + "|".join(align) + "|", *map(markdown_row, rows)]
