"""Plain-text tables for the ``summary()`` of result objects."""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["format_table", "format_number"]


def format_number(value: object, digits: int = 6) -> str:
    """Format a number compactly (``%.{digits}g``); other objects with ``str``."""
    if isinstance(value, bool) or value is None:
        return str(value)
    if isinstance(value, (int,)):
        return str(value)
    try:
        return f"{float(value):.{digits}g}"
    except (TypeError, ValueError):
        return str(value)


def format_table(
    headers: Sequence[str],
    rows: Sequence[Sequence[object]],
    *,
    title: str | None = None,
    digits: int = 6,
) -> str:
    """Render rows as an aligned text table with a rule under the header.

    Parameters
    ----------
    headers : sequence of str
        Column titles.
    rows : sequence of sequences
        Cell values; numbers are formatted with `digits` significant digits.
    title : str, optional
        A line printed above the table.
    digits : int
        Significant digits of numeric cells.
    """
    cells = [[format_number(c, digits) for c in row] for row in rows]
    widths = [len(h) for h in headers]
    for row in cells:
        if len(row) != len(headers):
            raise ValueError(f"row has {len(row)} cells, header has {len(headers)}")
        widths = [max(w, len(c)) for w, c in zip(widths, row)]
    lines = []
    if title:
        lines.append(title)
    lines.append("  ".join(h.rjust(w) for h, w in zip(headers, widths)))
    lines.append("  ".join("-" * w for w in widths))
    lines.extend("  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in cells)
    return "\n".join(lines)
