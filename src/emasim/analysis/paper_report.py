"""The paper beside us: its numbers, our tables, the headline figures and the report's text.

Nothing here runs a simulation: :mod:`emasim.experiments.reproduction` runs the experiments and
hands their metrics and figures to :func:`build_tables` and :func:`write_report`. ``emasim
reproduce`` writes, atomically:
``report.md`` and ``report.html`` (figures, tables 2-7 and the simulation figures' numbers with
the paper's values beside ours, the abstract's claims over paired replicas, the five headline
figures of the abstract, the ablation of the bench's elements, the assumptions and the tuning
record), ``tables.json`` (the same numbers for machines, with a ``claims`` object, a
``headline`` object and an ``ablation`` list),
``figures/*.png`` and ``runs/<experiment>/`` (every run, with its scenario and metadata).
The paper's numbers are in ``paper_results.toml`` beside this module (transcribed from the text).
"""

import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from ..jsonio import json_text
from ..output import write_new
from ..version import __version__
from .judged import (
    ABLATED_TABLES,
    BENCH_SINE_ROWS,
    BENCH_STEP_ROWS,
    HEADLINE,
    HYBRID_LABEL,
    PID_LABEL,
    figure_words,
    headline_metric,
)
from .pareto import equal_chatter_table
from .report import (
    BENCH_SETTLING_BAND,
    BENCH_STEADY_S,
    CHECK_TOLERANCE,
    DEAD_ZONE_MM,
    RECOVERY_FLOOR_MM,
    RECOVERY_FLOOR_RPM,
    RECOVERY_FRACTION,
    STEADY_FRACTION,
    TRUE_PREFIX,
)
from .tables import markdown_table, number_cell
from .units import unit_of
from .verdict_rule import MAX_PERCENT


@dataclass(frozen=True)
class Experiment:
    """A shipped scenario that reproduces part of the paper."""

    scenario: str
    paper_key: str  # section of paper_results.toml
    figures: str  # where in the paper


EXPERIMENTS = (
    Experiment("speed-step", "speed_step", "Fig. 5"),
    Experiment("speed-sine", "speed_sine", "Fig. 6"),
    Experiment("position-step", "position_step", "Fig. 8"),
    Experiment("bench-step", "bench_step", "Figs. 16-19, Tables 2-5"),
    Experiment("bench-sine", "bench_sine", "Figs. 20-23, Tables 6-7"),
    Experiment("cosim-step", "cosim_step", "Figs. 13-14"),
)
SWEEP_CLEARANCES_MM = (0.0, 0.01, 0.05, 0.1)


def paper_results() -> dict:
    """The paper's numbers (paper_results.toml)."""
    return tomllib.loads(resources.files(__package__).joinpath("paper_results.toml").read_text())


def reduction(before: float, after: float) -> float | None:
    """Relative reduction of a magnitude, (|before| - |after|) / |before|; None if undefined."""
    if before is None or after is None or not math.isfinite(before) or before == 0:
        return None
    return (abs(before) - abs(after)) / abs(before)


def variant_labels(ours: dict) -> list[str]:
    """The controller sets of a comparison beside PID and the hybrid (e.g. the industrial
    PID, with velocity feed-forward), in their order."""
    return [label for label in ours if label not in (PID_LABEL, HYBRID_LABEL)]


def bench_table(paper: dict, ours: dict, rows: dict) -> list[dict]:
    """Rows of a bench table: paper PID/hybrid, ours PID/hybrid, and both reductions; with
    ``variants`` {label: {value, hybrid_reduction}} for every further set of ours (the paper
    has none), the hybrid's reduction against it."""
    table = []
    for paper_key, (our_key, unit) in rows.items():
        p_pid, p_hyb = paper[PID_LABEL].get(paper_key), paper[HYBRID_LABEL].get(paper_key)
        o_pid, o_hyb = ours[PID_LABEL].get(our_key), ours[HYBRID_LABEL].get(our_key)
        true_key = TRUE_PREFIX + our_key  # the true angle's figure (the bench measures ours)
        t_pid, t_hyb = ours[PID_LABEL].get(true_key), ours[HYBRID_LABEL].get(true_key)
        others = {label: ours[label].get(our_key) for label in variant_labels(ours)}
        others_true = {label: ours[label].get(true_key) for label in variant_labels(ours)}
        numeric = all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in (p_pid, p_hyb)
        )
        if isinstance(p_pid, bool):  # a flag: ours as yes/no too, not 0/1
            o_pid, o_hyb = (None if v is None else bool(v) for v in (o_pid, o_hyb))
            others = {k: None if v is None else bool(v) for k, v in others.items()}
        table.append(
            {
                "metric": our_key,
                "unit": unit,
                "paper_pid": p_pid,
                "paper_hybrid": p_hyb,
                "ours_pid": o_pid,
                "ours_hybrid": o_hyb,
                "paper_reduction": reduction(p_pid, p_hyb) if numeric else None,
                "ours_reduction": reduction(o_pid, o_hyb) if numeric else None,
                "true_pid": t_pid,
                "true_hybrid": t_hyb,
                "true_reduction": reduction(t_pid, t_hyb) if numeric else None,
                "variants": {
                    label: {
                        "value": value,
                        "hybrid_reduction": reduction(value, o_hyb) if numeric else None,
                        "true_value": others_true[label],
                        "true_hybrid_reduction": (
                            reduction(others_true[label], t_hyb) if numeric else None
                        ),
                    }
                    for label, value in others.items()
                },
            }
        )
    return table


def headline(paper: dict, tables: dict) -> dict:
    """The abstract's five figures: paper values from its tables, ours from the same metric,
    and the hybrid against each further PID variant its experiment compares (``variants``)."""
    out = {}
    for name, (experiment, _, definition) in HEADLINE.items():
        our_key, unit = headline_metric(name)
        (row,) = [r for r in tables[experiment] if r["metric"] == our_key]
        out[name] = {
            "paper_pid": row["paper_pid"],
            "paper_hybrid": row["paper_hybrid"],
            "ours_pid": row["ours_pid"],
            "ours_hybrid": row["ours_hybrid"],
            "unit": unit,
            "definition": definition,
            "paper_abstract_reduction": paper["headline"][name],
            "paper_reduction": row["paper_reduction"],
            "ours_reduction": row["ours_reduction"],
            "hybrid_better": abs(row["ours_hybrid"]) < abs(row["ours_pid"]),
            "true_pid": row["true_pid"],  # the true rudder angle's figure, beside the measured
            "true_hybrid": row["true_hybrid"],
            "true_reduction": row["true_reduction"],
            "variants": row["variants"],  # the experiment's further PID sets, if any
        }
    return out


def simulation_tables(paper: dict, metrics: dict) -> dict:
    """Numbers of the simulation figures: Fig. 8 (position step) and Fig. 6 (speed sine)."""
    tables = {}
    if "position-step" in metrics:
        fig8 = paper["position_step"]
        tables["position_step"] = [
            {
                "controller": label,
                "paper_dead_zone_s": fig8["dead_zone_s"].get(label),
                "ours_dead_zone_s": m.get("dead_zone_time_s"),
                "paper_settling_s": fig8["settling_s"].get(label),
                "ours_settling_s": m.get("settling_time_s"),
                "paper_steady_error_mm": fig8["steady_error_mm"].get(label),
                "ours_steady_error_rms_mm": m.get("steady_error_rms_mm"),
            }
            for label, m in metrics["position-step"].items()
        ]
    if "speed-sine" in metrics:
        recovery = paper["speed_sine"]["recovery_s"]
        tables["speed_sine"] = [
            {
                "controller": label,
                "paper_recovery_s": recovery.get(label),
                "ours_recovery_s": m.get("load_recovery_time_s"),
                "ours_load_dip_rpm": m.get("load_dip_rpm"),
                "ours_load_steady_error_rpm": m.get("load_steady_error_mean_rpm"),
                "ours_max_error_rpm": m.get("max_error_rpm"),
            }
            for label, m in metrics["speed-sine"].items()
        ]
    for name in ("speed-step", "cosim-step"):
        if name in metrics:
            tables[name.replace("-", "_")] = [
                {"controller": label, **m} for label, m in metrics[name].items()
            ]
    return tables


def build_tables(metrics: dict) -> dict:
    """Every table of the report from {experiment: {label: metrics}}."""
    paper = paper_results()
    tables = simulation_tables(paper, metrics)
    if "bench-step" in metrics:
        tables["bench_step"] = bench_table(
            paper["bench_step"], metrics["bench-step"], BENCH_STEP_ROWS
        )
    if "bench-sine" in metrics:
        tables["bench_sine"] = bench_table(
            paper["bench_sine"], metrics["bench-sine"], BENCH_SINE_ROWS
        )
    if "bench_step" in tables and "bench_sine" in tables:
        tables["headline"] = headline(paper, tables)
    return tables


def ablation_rows(ablation: dict) -> list[dict]:
    """The ``ablation`` list of tables.json from {experiment: {stage: {label: metrics}}}: one
    row per experiment, stage and bench-table metric, the paper's bench values beside ours."""
    paper = paper_results()
    rows = []
    for name, stages in ablation.items():
        key = name.replace("-", "_")
        for stage, metrics in stages.items():
            for row in bench_table(paper[key], metrics, ABLATED_TABLES[key]):
                rows.append({"experiment": key, "stage": stage, **row})
    return rows


def _finite(value) -> bool:
    return isinstance(value, float) and math.isfinite(value)


def ablation_moves(rows: list[dict]) -> list[str]:
    """For each metric of the ablated tables and each controller, the stage that moves it
    most from the stage before, as report lines (measured: read off the rows)."""
    lines = []
    for key, table_rows in ABLATED_TABLES.items():
        for metric, _ in table_rows.values():
            series = [r for r in rows if r["experiment"] == key and r["metric"] == metric]
            for side, label in (("ours_pid", PID_LABEL), ("ours_hybrid", HYBRID_LABEL)):
                values = [(r["stage"], r[side]) for r in series]
                steps = [
                    (abs(after - before), stage, before, after)
                    for (_, before), (stage, after) in zip(values, values[1:], strict=False)
                    if _finite(before) and _finite(after)
                ]
                if steps and max(steps)[0] > 0.0:
                    _, stage, before, after = max(steps)
                    lines.append(
                        f"{key} {metric}, {label}: most moved by {stage} "
                        f"({number_cell(before)} -> {number_cell(after)})"
                    )
    return lines


def _ablation_markdown(rows: list[dict], key: str) -> str:
    """One row per metric of the table, one column per stage, PID / hybrid in each cell."""
    mine = [r for r in rows if r["experiment"] == key]
    stages = list(dict.fromkeys(r["stage"] for r in mine))
    value = {(r["stage"], r["metric"]): r for r in mine}

    def pair(stage: str, metric: str, side: str) -> str:
        row = value[stage, metric]
        return f"{number_cell(row[f'{side}_pid'])} / {number_cell(row[f'{side}_hybrid'])}"

    header = ["metric (PID / hybrid)", "unit", "paper bench", *stages]
    body = [
        [metric, unit, pair(stages[0], metric, "paper")]
        + [pair(stage, metric, "ours") for stage in stages]
        for metric, unit in ABLATED_TABLES[key].values()
    ]
    return markdown_table(header, body)


def definitions() -> list[str]:
    """The windows and bands behind the numbers, as report lines."""
    return [
        f"Bench steady-state statistics: from {BENCH_STEADY_S:g} s to the end of the run.",
        f"Bench settling time: into a {100 * BENCH_SETTLING_BAND:g} % band of the 4.72 deg "
        "step (the paper's PID oscillates by about 4 % of it).",
        "Simulation step metrics: 2 % settling band, on the interval before the load step; "
        f"steady error over the last {100 * STEADY_FRACTION:g} % of that interval; dead-zone "
        f"time until the rod has moved {DEAD_ZONE_MM * 1e3:g} um.",
        "Load step: the dip is the largest error after it; the recovery time runs until the "
        f"error stays within {100 * RECOVERY_FRACTION:g} % of the dip, or within "
        f"{RECOVERY_FLOOR_RPM:g} rpm (speed) or {RECOVERY_FLOOR_MM * 1e3:g} um (position) if "
        "that is wider, to the end of the run (speed sine: to the reference's next reversal, "
        "where friction disturbs the loop by itself); none (nan, '-' in a table) if the error is "
        "still outside then. The steady error under load is the mean and RMS error over the last "
        f"{100 * STEADY_FRACTION:g} % of that interval.",
        "Reductions are (|PID| - |hybrid|) / |PID| of the same metric.",
        "Rudder rate: the rod velocity through the lumped rudder arm (true value; the bench "
        "computed it from its encoder).",
    ]


def _pct(value) -> str:
    """A reduction in percent; '-' for none or one beyond +-MAX_PERCENT, which says no more
    than that the baseline is near zero (or round-off: emasim.analysis.verdict_rule)."""
    if value is None or not abs(100 * value) <= MAX_PERCENT:
        return "-"
    return f"{100 * value:.0f} %"


def _bench_markdown(table: list[dict]) -> str:
    """The paper's PID and hybrid beside ours, then each further set of ours (a PID variant)
    with the hybrid's reduction against it."""
    labels = list(table[0].get("variants", {})) if table else []
    header = [
        "metric",
        "unit",
        "paper PID",
        "paper hybrid",
        "paper reduction",
        "ours PID",
        "ours hybrid",
        "ours reduction",
        *(f"{text} {label}" for label in labels for text in ("ours", "reduction vs")),
    ]
    rows = [
        [
            r["metric"],
            r["unit"],
            number_cell(r["paper_pid"]),
            number_cell(r["paper_hybrid"]),
            _pct(r["paper_reduction"]),
            number_cell(r["ours_pid"]),
            number_cell(r["ours_hybrid"]),
            _pct(r["ours_reduction"]),
            *(
                cell
                for label in labels
                for cell in (
                    number_cell(r["variants"][label]["value"]),
                    _pct(r["variants"][label]["hybrid_reduction"]),
                )
            ),
        ]
        for r in table
    ]
    return markdown_table(header, rows)


def _dict_rows_markdown(rows: list[dict]) -> str:
    """One row per entry; a table of controllers is transposed (a row per metric, with its
    unit, a column per controller) so that it fits the page."""
    if "controller" not in rows[0]:
        header = list(rows[0])
        return markdown_table(header, [[number_cell(r[k]) for k in header] for r in rows])
    keys = list(dict.fromkeys(k for r in rows for k in r if k != "controller"))
    header = ["metric", "unit", *(r["controller"] for r in rows)]
    body = [[key, unit_of(key), *(number_cell(r.get(key)) for r in rows)] for key in keys]
    return markdown_table(header, body)


def _headline_markdown(items: dict) -> str:
    """The five figures: the paper's, ours as the bench measures them (the encoder), the true
    rudder angle's, and the hybrid against each further PID variant."""
    labels = list(dict.fromkeys(label for h in items.values() for label in h.get("variants", {})))
    header = [
        "figure",
        "unit",
        "paper PID",
        "paper hybrid",
        "paper reduction (abstract)",
        "ours PID",
        "ours hybrid",
        "ours reduction",
        "hybrid better",
        "true angle: PID",
        "true angle: hybrid",
        "true angle: reduction",
        *(f"{text} {label}" for label in labels for text in ("ours", "reduction vs")),
    ]
    rows = [
        [
            figure_words(name),
            h["unit"],
            number_cell(h["paper_pid"]),
            number_cell(h["paper_hybrid"]),
            f"{_pct(h['paper_reduction'])} ({_pct(h['paper_abstract_reduction'])})",
            number_cell(h["ours_pid"]),
            number_cell(h["ours_hybrid"]),
            _pct(h["ours_reduction"]),
            number_cell(h["hybrid_better"]),
            number_cell(h.get("true_pid")),
            number_cell(h.get("true_hybrid")),
            _pct(h.get("true_reduction")),
            *(
                cell
                for label in labels
                for cell in (
                    number_cell(h["variants"].get(label, {}).get("value")),
                    _pct(h["variants"].get(label, {}).get("hybrid_reduction")),
                )
            ),
        ]
        for name, h in items.items()
    ]
    return markdown_table(header, rows)


def _components_markdown(components: dict) -> list[str]:
    """The hybrid part by part (emasim.experiments.components): a table per bench experiment
    and the lines its numbers give."""
    from .components import component_lines, figures_of

    parts = [
        "## The hybrid part by part",
        "Each bench experiment's tuned hybrid with one part switched off at a time, and with "
        "its loops crossed with the PID cascade's (emasim.experiments.components); every "
        "other gain as tuned. Figures as the bench measures them, the true angle's in "
        "brackets.",
    ]
    for key, rows in components.items():
        figures = figures_of(key)
        header = ["controllers", *(f"{k} ({unit_of(k)})" for k in figures)]
        body = [
            [
                row["component"],
                *(
                    f"{number_cell(row[k])} ({number_cell(row.get(TRUE_PREFIX + k))})"
                    for k in figures
                ),
            ]
            for row in rows
        ]
        parts += [f"### {key.replace('_', '-')}", markdown_table(header, body)]
        parts.append("\n".join(f"- {line}" for line in component_lines(key, rows)))
    return parts


def _interval(low_high, scale: float = 1.0) -> str:
    low, high = (scale * v for v in low_high)
    return f"[{low:.0f}, {high:.0f}]" if math.isfinite(low) and math.isfinite(high) else "[-]"


def robustness_lines(verdicts: dict, headline: dict | None = None) -> list[str]:
    """Each figure's conclusion with its probability, as report lines; where the nominal
    bench's verdict (``headline``) goes against a clear Monte Carlo verdict, it says so."""
    lines = []
    for name, v in verdicts.items():
        if not v.get("runs"):
            continue
        what = figure_words(name)
        better = "lower" if v["win_rate"] >= 0.5 else "higher"
        line = (
            f"{what} ({v['scenario']} {v['metric']}): the hybrid's is lower than PID's on "
            f"{100 * v['win_rate']:.0f} % of {v['runs']} plants (95 % interval "
            f"{_interval(v['win_rate_ci95'], 100)} %), so it is {better} with probability "
            f"{100 * max(v['win_rate'], 1 - v['win_rate']):.0f} %; median improvement "
            f"{v['median_improvement_pct']:.0f} % {_interval(v['ci95_pct'])} %."
        )
        sensitive = v.get("most_sensitive_to") or {}
        if sensitive:
            line += (
                f" The improvement follows `{sensitive['parameter']}` most (Spearman "
                f"{sensitive['spearman']:+.2f})."
            )
        low, high = v["win_rate_ci95"]
        if not low < 0.5 < high and headline and name in headline:
            if headline[name]["hybrid_better"] != (low > 0.5):
                line += " The nominal bench's verdict goes the other way: it does not hold."
        elif low < 0.5 < high:
            line += " Not settled: the interval contains one half."
        lines.append(line)
        sensitivity = _sensitivity_line(what, v)
        if sensitivity:
            lines.append(sensitivity)
    return lines


def _sensitivity_line(what: str, v: dict) -> str:
    """The figure's sensitivity against each baseline: the parameter that moves its win rate
    most, with the win rate in that parameter's lower, middle and upper third."""
    parts = []
    for baseline, verdict in (v.get("against") or {PID_LABEL: v}).items():
        most = verdict.get("moves_most") or {}
        if most:
            rates = verdict["sensitivity_thirds"][most["parameter"]]
            shown = " / ".join("-" if r is None else f"{100 * r:.0f}" for r in rates)
            parts.append(f"against {baseline} {most['parameter']} ({shown} %)")
    if not parts:
        return ""
    return (
        f"{what}, what moves the win rate most (the win rate in its lower / middle / upper "
        f"third): " + "; ".join(parts) + "."
    )


def _robustness_markdown(verdicts: dict, uncertainty: str, headline: dict) -> list[str]:
    header = ["figure", "experiment", "runs", "hybrid wins", "95 % interval", "median gain"]
    rows = [
        [
            figure_words(name),
            v["scenario"],
            str(v["runs"]),
            f"{100 * v['win_rate']:.0f} %",
            f"{_interval(v['win_rate_ci95'], 100)} %",
            f"{v['median_improvement_pct']:.0f} % {_interval(v['ci95_pct'])}",
        ]
        for name, v in verdicts.items()
        if v.get("runs")
    ]
    return [
        "## Robustness over the bench's plant uncertainty",
        "A Monte Carlo of each bench experiment, the gains fixed at their nominal tuning, PID, "
        "the industrial PID and the hybrid on the same sampled plants "
        "(emasim.experiments.robustness), each parameter drawn uniformly (log-uniformly for a "
        "factor of 2 either way; a `*` scales the bench's value) over its range:",
        uncertainty,
        "Hybrid wins: the fraction of plants on which its |metric| is below PID's (a diverged "
        "run loses), with its exact (Clopper-Pearson) 95 % interval; median gain: of "
        "100 (|PID| - |hybrid|) / |PID|, with its distribution-free 95 % interval. What moves "
        "the win rate most: of the sampled parameters (the seed left out), the one whose lower, "
        "middle and upper thirds of values give the most different win rates.",
        markdown_table(header, rows),
        "\n".join(f"- {line}" for line in robustness_lines(verdicts, headline)),
    ]


def _wear_markdown(degradation: dict, figures: list) -> list[str]:
    levels = next(iter(degradation.values()))["levels"]
    header = ["figure", "controller set", *(f"level {k}" for k in levels)]
    rows = [
        [figure_words(name), label, *entry[label]]
        for name, entry in degradation.items()
        for label in (PID_LABEL, HYBRID_LABEL)
    ]
    return [
        "## Wear: the headline figures over the service life",
        "Each bench experiment with the gains at their nominal tuning, from new (level 0, the "
        "nominal bench) to worn (level 4): the screw backlash x(1 + k/2), every hinge "
        "clearance x(1 + k) and friction x(1 + k/4) at level k (emasim.experiments.wear; SAE "
        "AIR5713's service-life concern).",
        *(f"![{caption}]({path})" for caption, path in figures),
        markdown_table(header, rows),
    ]


def fronts_of(tuning: dict | None) -> dict:
    """label -> [tuning.sets] record, for the sets whose record has a Pareto front."""
    sets = (tuning or {}).get("sets", {})
    return {label: record for label, record in sets.items() if record.get("front")}


def pareto_markdown(tuning: dict | None) -> list[str]:
    """The controller sets compared at equal chattering, from their tuning fronts
    (emasim.analysis.pareto): at each set's tuned chattering, the best tracking every set
    reaches without chattering more; nothing for a record without fronts."""
    sets = fronts_of(tuning)
    if len(sets) < 2:
        return []
    rows = equal_chatter_table(
        {label: record["front"] for label, record in sets.items()},
        {label: record["tuned_point"][0] for label, record in sets.items()},
    )
    header = ["at the chattering of", "chattering (1/s)", *(f"{label} tracking" for label in sets)]
    body = [
        [
            row["at the chattering of"],
            number_cell(row["chatter"]),
            *(number_cell(row[label]) for label in sets),
        ]
        for row in rows
    ]
    return [
        "Tracking at equal chattering (each set's Pareto front of its tuning trials; a dash: "
        "no trial of that set chatters so little). The tuned points weigh the two terms with "
        "one weight; the front shows every weight.",
        markdown_table(header, body),
    ]


def tuning_sentence(tuning: dict | None, at_limit: dict | None = None) -> str:
    """How an experiment's gains were obtained, from its scenario's ``[tuning]`` record: the
    rule, and per controller set the trials it used, why it stopped, the ranges widened and
    any optimum still on a bound, and the check of its neighbourhood (a record of an older
    emasim gives one trial count)."""
    if not tuning:
        return "the scenario's defaults (not tuned)."
    if "sets" not in tuning:
        return (
            f"tuned ({tuning['method']}; {tuning['trials_per_controller_set']} "
            f"trials per controller set; cost `{tuning['cost']}`)."
        )
    sets = []
    for label, record in tuning["sets"].items():
        text = f"{label} {record['trials']} trials for {record['knobs']} knobs ({record['stopped']}"
        text += "".join(
            f"; {key} widened to [{low:.4g}, {high:.4g}]"
            for key, (low, high) in record.get("widened", {}).items()
        )
        limits = (at_limit or {}).get(label, {})
        text += "".join(
            f"; **optimum on the {side} bound of {key}**"
            + (f", the law's own limit ({limits[key]})" if key in limits else "")
            for key, side in record.get("on_bound", {}).items()
        )
        check = record.get("neighbourhood")
        if check:
            ratio = check["best_cost_ratio"]
            text += (
                f"; of {check['points']} points within x1.5 of each knob the best costs "
                f"{ratio:.3f} of the optimum"
                + (" (converged)" if ratio >= 1 - CHECK_TOLERANCE else ", **not converged**")
            )
        sets.append(text + ")")
    batch = f"; {tuning['batch']} trials at a time" if "batch" in tuning else ""
    return (
        f"tuned ({tuning['method']}; {tuning['budget']}{batch}; seed {tuning['seed']}; "
        f"cost `{tuning['cost']}`): " + ", ".join(sets) + "."
    )


def write_report(
    folder: Path,
    tables: dict,
    scenarios: dict,
    figures: dict,
    notes: str,
    stages: tuple = (),
    uncertainty: str = "",
    at_limit: dict | None = None,
) -> None:
    """report.md, report.html and tables.json into ``folder``; ``stages`` names and describes
    the ablation's stages, when ``tables`` has an ablation; ``uncertainty`` the table
    (Markdown) of the robustness study's --vary specs, when ``tables`` has its verdicts
    (``robustness``); ``at_limit`` scenario -> label -> {knob: why} for each optimum on a bound
    that is its law's own limit (emasim.tuning.bounds_at_limit), named in the Gains line."""
    parts = [
        "# emasim reproduction of Ding & Zhou (2025)",
        f"emasim {__version__}. Hybrid = position RBF+SMC over speed super-twisting + GPIO; "
        "PID = position PID over speed PI (no feed-forward, the paper's conventional "
        "baseline); industrial PID = the same with velocity and acceleration "
        "feed-forward (the derivative on the measurement in both). All run over the same "
        "current loop on the same virtual bench.",
    ]
    if tables.get("claims"):
        from .claims import markdown as claims_markdown

        parts += claims_markdown(tables["claims"])
        if tables.get("run_length"):
            from .claims import length_markdown

            parts += length_markdown(tables["run_length"])
    elif "headline" in tables:
        parts += [
            "## The abstract's claims over paired replicas",
            "No replica study of these experiments and this emasim version yet: "
            "`emasim reproduce` runs one (`--replicas N`, default 16); the single runs "
            "below decide nothing.",
        ]
    if "headline" in tables:
        parts += ["## The abstract's five figures", _headline_markdown(tables["headline"])]
    if tables.get("robustness"):
        parts += _robustness_markdown(tables["robustness"], uncertainty, tables.get("headline", {}))
    elif "headline" in tables:
        parts += [
            "## Robustness over the bench's plant uncertainty",
            "No robustness study of these experiments and this emasim version yet: "
            "`emasim reproduce --robustness` runs one (minutes).",
        ]
    if tables.get("verdict_map"):
        from .verdict_map import markdown as verdict_map_markdown

        drawn = figures.get("verdict_map", [None])[0]
        parts += verdict_map_markdown(tables["verdict_map"], drawn)
    elif "headline" in tables:
        parts += [
            "## Where each verdict flips",
            "No verdict map of these experiments and this emasim version yet: "
            "`emasim reproduce --robustness` makes one with the Monte Carlo.",
        ]
    if tables.get("components"):
        parts += _components_markdown(tables["components"])
    for exp in EXPERIMENTS:
        if exp.scenario not in scenarios:
            continue
        sc = scenarios[exp.scenario]
        parts.append(f"## {exp.scenario} ({exp.figures})")
        parts.append(sc.get("description", ""))
        for caption, path in figures.get(exp.scenario, []):
            parts.append(f"![{caption}]({path})")
        key = exp.paper_key
        if key in ("bench_step", "bench_sine"):
            parts.append(_bench_markdown(tables[key]))
        elif key in tables:
            parts.append(_dict_rows_markdown(tables[key]))
        if key == "cosim_step" and "clearance_sweep" in tables:
            parts.append(
                "Clearance sweep (whole runs of the same experiment, every "
                "hinge at the clearance shown):"
            )
            parts.append(_dict_rows_markdown(tables["clearance_sweep"]))
        limits = (at_limit or {}).get(exp.scenario)
        parts.append("Gains: " + tuning_sentence(sc.get("tuning"), limits))
        parts += pareto_markdown(sc.get("tuning"))
    if tables.get("wear"):
        parts += _wear_markdown(tables["wear"], figures.get("wear", []))
    if tables.get("ablation"):
        parts += [
            "## Ablation: the bench's elements one at a time",
            "Each bench comparison re-run with the same tuned gains as the elements are added "
            "(emasim.experiments.ablation): "
            + "; ".join(f"**{name}**: {text}" for name, text in stages)
            + ".",
        ]
        for key in ABLATED_TABLES:
            if any(r["experiment"] == key for r in tables["ablation"]):
                parts += [
                    f"### {key.replace('_', '-')}",
                    _ablation_markdown(tables["ablation"], key),
                ]
        parts.append("\n".join(f"- {line}" for line in ablation_moves(tables["ablation"])))
    parts += ["## Definitions", "\n".join(f"- {line}" for line in definitions())]
    parts.append(notes)
    text = "\n\n".join(parts) + "\n"
    write_new(folder / "report.md", text)
    write_new(folder / "report.html", report_html(text, "emasim reproduction"))
    write_new(folder / "tables.json", json_text(tables))


def report_html(markdown_text: str, title: str) -> str:
    """The report's HTML: its Markdown (tables, code: a formula in backticks stays literal)
    inside the Jinja2 page template ``report.html.j2``, the title escaped."""
    import markdown
    from jinja2 import Environment, select_autoescape

    body = markdown.markdown(markdown_text, extensions=["tables"])
    template = Environment(autoescape=select_autoescape(default=True)).from_string(
        resources.files(__package__).joinpath("report.html.j2").read_text()
    )
    return template.render(title=title, body=body)


NOTES_FILE = "reproduction_notes.md"


def notes() -> str:
    """The assumptions and the discussion of where we differ (reproduction_notes.md)."""
    return resources.files(__package__).joinpath(NOTES_FILE).read_text()
