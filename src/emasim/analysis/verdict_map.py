"""What the verdict map says (its runs: emasim.experiments.verdict_map).

A cell's verdict is the sign of its margin, 100 (|baseline| - |hybrid|) / |baseline|: the hybrid
wins where it is positive. tables.json writes an infinite number as null: a null margin is -inf
(the hybrid alone diverged, or its figure is above the baseline's 0), a null figure a run that
diverged. :func:`flip_lines` reads, for each headline figure and baseline, the
nominal bench's verdict, how many cells the hybrid wins, and along each axis through the nominal
cell (the other axes held nominal) the values between which the verdict flips; cells off those
lines that go the other way are counted. :func:`markdown` is the report's section.
"""

import math

from .judged import figure_words
from .tables import markdown_table
from .units import unit_of

AXIS_NAMES = {  # axis -> (how a line names it, its unit)
    "preload_Nm": ("the preload", "N·m"),
    "encoder": ("the encoder", ""),
    "hinge_clearance_mm": ("the hinge clearance", "mm"),
}


def _shown(axis: str, value) -> str:
    unit = AXIS_NAMES[axis][1]
    return f"{value:g} {unit}" if unit else str(value)


def margin(baseline: float, hybrid: float) -> float:
    """100 (|baseline| - |hybrid|) / |baseline| of two magnitudes: 100 when only the baseline
    diverged (inf), -inf when only the hybrid did, 0 when both did or both are 0."""
    if math.isinf(baseline):
        return 0.0 if math.isinf(hybrid) else 100.0
    if math.isinf(hybrid):
        return -math.inf
    if baseline == 0.0:
        return 0.0 if hybrid == 0.0 else -math.inf
    return 100.0 * (baseline - hybrid) / baseline


def margin_of(cell: dict) -> float:
    """The cell's margin (%), -inf where tables.json holds null."""
    value = cell["margin_pct"]
    return -math.inf if value is None else value


def _figure(value) -> str:
    return "diverged" if value is None or math.isinf(value) else f"{value:.3g}"


def _wins(cell: dict) -> bool:
    return margin_of(cell) > 0.0


def cell_at(cells: list[dict], place: dict) -> dict:
    """The cell at ``place`` (axis -> value)."""
    return next(c for c in cells if all(c[axis] == v for axis, v in place.items()))


def along(cells: list[dict], nominal: dict, axis: str) -> list[dict]:
    """The cells on ``axis``'s line through the nominal cell, in the axis' order."""
    others = {a: v for a, v in nominal.items() if a != axis}
    return [c for c in cells if all(c[a] == v for a, v in others.items())]


def flips(cells: list[dict], nominal: dict, axis: str) -> list[tuple]:
    """(value, next value) wherever the verdict changes between neighbours on ``axis``'s line
    through the nominal cell."""
    line = along(cells, nominal, axis)
    return [
        (a[axis], b[axis]) for a, b in zip(line, line[1:], strict=False) if _wins(a) != _wins(b)
    ]


def wins_by_value(cells: list[dict], axis: str) -> dict:
    """value of ``axis`` -> (cells the hybrid wins, cells) over the whole map."""
    out = {}
    for cell in cells:
        won, count = out.get(cell[axis], (0, 0))
        out[cell[axis]] = (won + _wins(cell), count + 1)
    return out


def flip_line(name: str, metric: str, baseline: str, cells: list[dict], nominal: dict) -> str:
    """One headline figure's (``name``, read on ``metric``) verdict against one baseline, from
    its cells (module docstring): on the nominal bench, the cells won, one condition at a time
    from the nominal bench, and the wins by each condition's value over the whole map."""
    home = cell_at(cells, nominal)
    wins = sum(_wins(c) for c in cells)
    verdict = "wins" if _wins(home) else "loses"
    text = (
        f"{figure_words(name)} against {baseline}: on the "
        f"nominal bench the hybrid {verdict} ({_figure(home['baseline'])} against "
        f"{_figure(home['hybrid'])} {unit_of(metric)}, margin {_margin(margin_of(home))}); it "
        f"wins in {wins} of {len(cells)} cells"
    )
    if wins in (0, len(cells)):
        return text + ": the verdict holds over the whole map."
    parts = []
    for axis, (axis_name, _) in AXIS_NAMES.items():
        line = along(cells, nominal, axis)
        found = flips(cells, nominal, axis)
        if not found:
            low, high = line[0][axis], line[-1][axis]
            parts.append(f"{axis_name} it holds ({_shown(axis, low)} to {_shown(axis, high)})")
            continue
        steps = ", then back between ".join(
            f"{_shown(axis, a)} and {_shown(axis, b)}" for a, b in found
        )
        parts.append(f"{axis_name} it flips between {steps}")
    counts = []
    for axis, (axis_name, _) in AXIS_NAMES.items():
        by = wins_by_value(cells, axis)
        values = ", ".join(_shown(axis, v) for v in by)
        won = ", ".join(str(w) for w, _ in by.values())
        counts.append(
            f"{axis_name.removeprefix('the ')} {values}: {won} of {next(iter(by.values()))[1]}"
        )
    return (
        f"{text}. From the nominal bench, one condition at a time: along "
        + "; along ".join(parts)
        + ". Its wins by condition over the map: "
        + "; ".join(counts)
        + "."
    )


def flip_lines(vmap: dict) -> list[str]:
    """:func:`flip_line` for every figure of the map and every baseline."""
    return [
        flip_line(name, entry["metric"], baseline, cells, vmap["nominal"])
        for name, entry in vmap["figures"].items()
        for baseline, cells in entry["against"].items()
    ]


def _margin(value: float) -> str:
    """'+56 %', one decimal below 1 % ('+0.4 %': never a bare 0 for a margin), '-inf'."""
    if not math.isfinite(value):
        return "-inf"
    return f"{value:+.0f} %" if abs(value) >= 0.95 or value == 0 else f"{value:+.1f} %"


def markdown(vmap: dict, figure: tuple[str, str] | None = None) -> list[str]:
    """The report's section: how the map was made, its figure (caption, path), a table of
    margins per headline figure and baseline (rows: encoder and hinge clearance; columns: the
    preload; the nominal cell in bold) and :func:`flip_lines`."""
    axes, nominal = vmap["axes"], vmap["nominal"]
    parts = [
        "## Where each verdict flips",
        "Each bench experiment re-run, the gains as tuned, at every cell of a grid of the "
        "conditions the verdicts hang on (emasim.experiments.verdict_map): the load motor's "
        f"standing preload ({', '.join(f'{p:g}' for p in axes['preload_Nm'])} N m, 0 to the "
        f"loader's rating), the rudder encoder ({' or '.join(axes['encoder'])}) and every "
        f"hinge's clearance ({', '.join(f'{c:g}' for c in axes['hinge_clearance_mm'])} mm). "
        "A cell's margin is 100 (|baseline| - |hybrid|) / |baseline| on the figure as the bench "
        "measures it: positive, the hybrid wins. The nominal bench's cell is in bold.",
    ]
    if figure is not None:
        parts.append(f"![{figure[0]}]({figure[1]})")
    header = ["encoder, clearance", *(f"{p:g} N m" for p in axes["preload_Nm"])]
    for name, entry in vmap["figures"].items():
        for baseline, cells in entry["against"].items():
            body = []
            for encoder in axes["encoder"]:
                for clearance in axes["hinge_clearance_mm"]:
                    row = [f"{encoder}, {clearance:g} mm"]
                    for preload in axes["preload_Nm"]:
                        place = {
                            "preload_Nm": preload,
                            "encoder": encoder,
                            "hinge_clearance_mm": clearance,
                        }
                        cell = cell_at(cells, place)
                        shown = _margin(margin_of(cell))
                        row.append(f"**{shown}**" if place == nominal else shown)
                    body.append(row)
            title = figure_words(name)
            parts += [f"### {title}, hybrid against {baseline}", markdown_table(header, body)]
    parts.append("\n".join(f"- {line}" for line in flip_lines(vmap)))
    return parts
