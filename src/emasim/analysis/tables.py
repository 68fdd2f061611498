"""Markdown tables of numbers, as the reports print them."""

import math
import re


def number_cell(value) -> str:
    """A table cell: three significant figures, in fixed point from 1e-3 to 1e6 (1110, not
    1.11e+03), '-' for none, yes/no for a flag."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, str):
        return value
    if not math.isfinite(value):
        return str(value)
    if value == 0 or not 1e-3 <= abs(value) < 1e6:
        return f"{value:.3g}"
    decimals = max(0, 2 - math.floor(math.log10(abs(value))))
    return f"{value:.{decimals}f}"


NUMBER_CELL = re.compile(r"^([-+−]?[\d.]+(e[-+]?\d+)?( %)?|-|nan|inf|-inf)$")


def markdown_table(header: list[str], rows: list[list]) -> str:
    """A Markdown table; columns of numbers right-aligned, columns of text left-aligned."""
    cells = [[number_cell(c) if not isinstance(c, str) else c for c in row] for row in rows]
    numeric = [all(NUMBER_CELL.match(row[i]) for row in cells) for i in range(len(header))]
    lines = [
        "| " + " | ".join(header) + " |",
        "|" + "".join("---:|" if n else ":---|" for n in numeric),
    ]
    lines += ["| " + " | ".join(row) + " |" for row in cells]
    return "\n".join(lines)
