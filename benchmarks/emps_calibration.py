"""emasim identify on the EMPS benchmark, beside the benchmark's published results.

    python benchmarks/emps_calibration.py            # measure and print the docs block
    python benchmarks/emps_calibration.py --write    # and rewrite docs/calibration.md's block
                                                     # and docs/emps-fit.png

EMPS: A. Janot, M. Gautier, M. Brunot, *Data Set and Reference Models of EMPS*, 2019 Workshop on
Nonlinear System Identification Benchmarks. The data and the published results are read from
``../shared/data/emps/`` (``SOURCE.md``'s tables); nothing is copied into the project.
What it measures, on the training set DATA_EMPS and the cross-validation set
DATA_EMPS_PULSES (simulated from its own reference and pulses with the training set's values,
the benchmark's protocol):

- IDIM-LS, symmetric (M, Fv, Fc, offset) and asymmetric (M, Fv+, Fc+, Fv-, Fc-) friction; the
  inverse model's relative error on the training set and its cross-test on the pulses set;
- the output-error fit of each, its free-run relative errors on both sets and its time;
- LuGre (output-error, from the symmetric fit) against Coulomb + viscous on the pulses set;
- the computation delay: how well the law of a sample's readings explains the command recorded
  at that sample, and the force error of the published parameters with none and with one
  sample of delay (the reasoning of emps.toml's ``computation_delay_s``).

``tests/test_emps.py`` runs :func:`measure` and checks the published figures and that the docs
block is :func:`render` of what it measured (the seconds aside: they vary).
"""

import argparse
import re
import sys
import time
from pathlib import Path

from emasim.page_blocks import write_block

ROOT = Path(__file__).resolve().parents[1]
EMPS = ROOT.parent / "shared" / "data" / "emps"
DOCS = ROOT / "docs" / "calibration.md"
FIGURE = ROOT / "docs" / "emps-fit.png"
BLOCK = "emps-figures"
TRAIN = "DATA_EMPS.mat"
PULSES = "DATA_EMPS_PULSES.mat"

SYMMETRIC = [
    "plant.mass_kg",
    "plant.friction.viscous_Ns_per_m",
    "plant.friction.coulomb_N",
    "plant.friction.offset_N",
]
ASYMMETRIC_SETTINGS = [
    'plant.friction.model="asymmetric"',
    "plant.friction.coulomb_negative_N=20.0",
    "plant.friction.viscous_negative_Ns_per_m=200.0",
]
ASYMMETRIC = [  # the published asymmetric model has no offset (it would be collinear)
    "plant.mass_kg",
    "plant.friction.viscous_Ns_per_m",
    "plant.friction.coulomb_N",
    "plant.friction.viscous_negative_Ns_per_m=0:2000",
    "plant.friction.coulomb_negative_N=0:200",
]
LUGRE_SETTINGS = [
    'plant.friction.model="lugre"',
    # h = 50 us: the bristle's decay sigma0 |v| / Fs at the upper sigma0 and 0.2 m/s is
    # 4e4 1/s, h x rate = 2 < 2.78
    "loop.substeps=20",
]
LUGRE = [
    *SYMMETRIC,
    "plant.friction.static_N=0:100",
    "plant.friction.stribeck_speed_m_s=0.0001:0.05",
    # presliding travel Fc / sigma0 from 200 um down to 7 um; above 3e6 N/m the bristle needs
    # shorter sub-steps than 20 per ms
    "plant.friction.bristle_stiffness_N_per_m=1e5:3e6",
]
LUGRE_START = [  # the presliding parameters' starting point: 1 mm/s, 20 um of presliding travel
    "plant.friction.static_N=22.0",
    "plant.friction.stribeck_speed_m_s=0.005",
    "plant.friction.bristle_stiffness_N_per_m=1e6",
]
NAMES = {  # docs name, SOURCE.md row and column
    "plant.mass_kg": "M (kg)",
    "plant.friction.viscous_Ns_per_m": "Fv (N s/m)",
    "plant.friction.coulomb_N": "Fc (N)",
    "plant.friction.offset_N": "offset (N)",
    "plant.friction.viscous_negative_Ns_per_m": "Fv- (N s/m)",
    "plant.friction.coulomb_negative_N": "Fc- (N)",
}
ERRORS = ("position_m", "velocity_m_s", "acceleration_m_s2", "command_V")


def published() -> dict:
    """SOURCE.md's published results: IDIM-LS values (symmetric, asymmetric), the IDIM
    relative errors, the cross-test, and the forward simulation's relative errors (%)."""
    text = (EMPS / "SOURCE.md").read_text()

    def row(label: str) -> list[str]:
        line = next(li for li in text.splitlines() if li.startswith(f"| {label}"))
        return [cell.strip() for cell in line.strip().strip("|").split("|")[1:]]

    def number(cell: str) -> float:
        return float(cell.replace("−", "-").replace("%", "").replace(" ", ""))

    def pair(cell: str) -> tuple[float, float]:
        plus, minus = cell.split("/")
        return number(plus), number(minus)

    mass, viscous, coulomb, offset = (row(r) for r in ("mass", "viscous", "Coulomb", "offset"))
    fv_plus, fv_minus = pair(viscous[1])
    fc_plus, fc_minus = pair(coulomb[1])
    forward = {name: [number(c) for c in row(name)] for name in ("training set", "pulses set")}
    return {
        "symmetric": {
            SYMMETRIC[0]: number(mass[0]),
            SYMMETRIC[1]: number(viscous[0]),
            SYMMETRIC[2]: number(coulomb[0]),
            SYMMETRIC[3]: number(offset[0]),
        },
        "asymmetric": {
            SYMMETRIC[0]: number(mass[1]),
            SYMMETRIC[1]: fv_plus,
            SYMMETRIC[2]: fc_plus,
            "plant.friction.viscous_negative_Ns_per_m": -fv_minus,
            "plant.friction.coulomb_negative_N": -fc_minus,
        },
        "idim_error_pct": [number(c) for c in row("IDIM relative error")],
        "cross_test_pct": number(re.search(r"pulses file: ([\d.]+) %", text).group(1)),
        # position, velocity, acceleration, force (%)
        "forward_pct": {"training": forward["training set"], "pulses": forward["pulses set"]},
    }


def _identify(method, fit, settings=(), validate=True):
    from emasim.identification.identify import identify

    started = time.perf_counter()
    result = identify(
        "emps",
        EMPS / TRAIN,
        fit=fit,
        method=method,
        settings=list(settings),
        validate=[EMPS / PULSES] if validate else [],
    )
    return result, time.perf_counter() - started


def _delay_errors() -> dict[str, float]:
    """The force error (%) of the published symmetric parameters with no and with one
    sample of computation delay, on the training set."""
    from emasim.identification.axis_model import AxisModel
    from emasim.scenarios.axis_scenario import read_axis_raw

    values = published()["symmetric"]
    found = {}
    for delay in (0.0, 0.001):
        raw, source, _ = read_axis_raw("emps")
        raw["loop"]["computation_delay_s"] = delay
        model = AxisModel.read(raw, source, EMPS / TRAIN, {})
        errors, _ = model.errors(model.with_values(values))
        found[f"{delay * 1e3:g} ms"] = 100 * errors["command_V"]
    return found


def _law_residual_V() -> float:
    """The rms (V) of the recorded command less the description's law (eq. 6, the FIR
    velocity) of the readings of the same sample, on the training set: how well the law at
    lag 0 explains what was recorded."""
    import numpy as np
    import scipy.io

    data = scipy.io.loadmat(EMPS / TRAIN)
    q, r, u = (data[k].ravel() for k in ("qm", "qg", "vir"))
    kp, kv, ts = data["kp"].item(), data["kv"].item(), float(np.mean(np.diff(data["t"].ravel())))
    law = kv * (kp * (r[2:] - q[2:]) - (q[2:] - q[:-2]) / (2.0 * ts))
    return float(np.sqrt(np.mean((u[2:] - law) ** 2)))


def measure() -> dict:
    """Every figure of the module docstring, by name."""
    from emasim.identification.axis_model import AxisModel
    from emasim.scenarios.axis_scenario import read_axis_raw
    from emasim.scenarios.loader import apply_setting

    results = {"published": published()}
    for name, fit, settings in (
        ("symmetric", SYMMETRIC, ()),
        ("asymmetric", ASYMMETRIC, ASYMMETRIC_SETTINGS),
    ):
        idim, idim_s = _identify("idim", fit, settings, validate=False)
        raw, source, _ = read_axis_raw("emps")
        for item in settings:
            apply_setting(raw, item)
        pulses = AxisModel.read(raw, source, EMPS / PULSES, {})
        cross = pulses.inverse_error(idim.values)
        oe, oe_s = _identify("output-error", fit, settings)
        results[name] = {
            "idim": {k: [v, idim.idim.std[k]] for k, v in idim.values.items()},
            "idim_error_pct": 100 * idim.idim.relative_error,
            "idim_condition": idim.idim.condition,
            "cross_test_pct": 100 * cross,
            "idim_s": idim_s,
            "output_error": oe.values,
            "training": oe.errors,
            "pulses": oe.validation[str(EMPS / PULSES)],
            "output_error_s": oe_s,
            "simulations": oe.fit.evaluations,
        }
        if name == "symmetric":
            symmetric_fit = oe
    start = [f"{k}={v!r}" for k, v in symmetric_fit.values.items()]
    lugre, lugre_s = _identify("output-error", LUGRE, [*LUGRE_SETTINGS, *start, *LUGRE_START])
    results["lugre"] = {
        "output_error": lugre.values,
        "on_bound": lugre.on_bound,
        "training": lugre.errors,
        "pulses": lugre.validation[str(EMPS / PULSES)],
        "output_error_s": lugre_s,
    }
    results["delay_force_pct"] = _delay_errors()
    results["law_residual_V"] = _law_residual_V()
    results["figure"] = symmetric_fit
    return results


def _pct(value: float) -> str:
    return f"{value:.3g} %"


def _within(ours: float, theirs: float) -> str:
    return f"{100 * (ours - theirs) / abs(theirs):+.2f} %"


def render(results: dict) -> str:
    """The docs block's body: markdown tables of :func:`measure`'s figures."""
    pub = results["published"]
    lines = [""]
    for name, title in (("symmetric", "symmetric friction"), ("asymmetric", "asymmetric")):
        ours = results[name]
        lines += [
            f"**IDIM-LS, {title}** (training set; ± one standard deviation):",
            "",
            "| parameter | emasim | published | difference |",
            "|---|---:|---:|---:|",
        ]
        for key, (value, std) in ours["idim"].items():
            theirs = pub[name][key]
            label = NAMES[key].replace("Fv (", "Fv+ (" if name == "asymmetric" else "Fv (")
            label = label.replace("Fc (", "Fc+ (" if name == "asymmetric" else "Fc (")
            difference = _within(value, theirs)
            lines.append(f"| {label} | {value:.4f} ± {std:.3g} | {theirs} | {difference} |")
        index = 0 if name == "symmetric" else 1
        lines += [
            "",
            f"Inverse model's relative error {_pct(ours['idim_error_pct'])} (published "
            f"{pub['idim_error_pct'][index]} %), condition number {ours['idim_condition']:.3g}"
            + (
                f"; its cross-test on the pulses set {_pct(ours['cross_test_pct'])} (published "
                f"{pub['cross_test_pct']} %)."
                if name == "symmetric"
                else f"; cross-test on the pulses set {_pct(ours['cross_test_pct'])}."
            ),
            f"IDIM-LS took {ours['idim_s']:.2g} s, the output-error fit "
            f"{ours['output_error_s']:.2g} s ({ours['simulations']} simulations of 25 s).",
            "",
        ]
    lines += [
        "**Free-run closed-loop simulation** with the output-error values: relative errors "
        "|y - y_sim| / |y| (the force is g_tau times the drive's input), and the position RMSE;"
        " the published reference model (IDIM-LS values, symmetric friction) beside them:",
        "",
        "| set, model | position | velocity | acceleration | force | position RMSE |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for set_name, label in (("training", "training"), ("pulses", "pulses (cross-validation)")):
        for model in ("symmetric", "asymmetric", "lugre"):
            errors = results[model][set_name]
            cells = " | ".join(_pct(100 * errors[e]) for e in ERRORS)
            lines.append(
                f"| {label}, {model} | {cells} | {errors['position_rmse_mm'] * 1e3:.3g} µm |"
            )
        theirs = " | ".join(f"{v} %" for v in pub["forward_pct"][set_name])
        lines.append(f"| {label}, published | {theirs} | not given |")
    lugre = results["lugre"]
    values = lugre["output_error"]
    bound = ", ".join(f"`{k}` on its {v} bound" for k, v in lugre["on_bound"].items()) or "none"
    better = lugre["pulses"]["command_V"] < results["symmetric"]["pulses"]["command_V"]
    lines += [
        "",
        f"**LuGre** (output-error, {lugre['output_error_s']:.2g} s): Fc "
        f"{values['plant.friction.coulomb_N']:.4g} N, Fs {values['plant.friction.static_N']:.4g}"
        f" N, vs {1e3 * values['plant.friction.stribeck_speed_m_s']:.3g} mm/s, sigma0 "
        f"{values['plant.friction.bristle_stiffness_N_per_m']:.3g} N/m, Fv "
        f"{values['plant.friction.viscous_Ns_per_m']:.4g} N s/m (keys on a bound: {bound}). On "
        "the pulses set its force error is "
        f"{_pct(100 * lugre['pulses']['command_V'])} against Coulomb + viscous's "
        f"{_pct(100 * results['symmetric']['pulses']['command_V'])}: LuGre "
        + ("improves on it." if better else "does not improve on it."),
        "",
        "**Computation delay**: the recorded drive input at a sample is the law of the "
        f"readings of that sample to {results['law_residual_V']:.2g} V rms; with the published "
        "parameters the training set's force error is "
        + " and ".join(f"{v:.3g} % with {k}" for k, v in results["delay_force_pct"].items())
        + " of delay, so emps.toml applies the command from its own sample.",
        "",
    ]
    return "\n".join(lines)


SECONDS = re.compile(r"\d[\d.]* s\b")


def without_seconds(block: str) -> str:
    """The block with every time in seconds masked (they vary from run to run)."""
    return SECONDS.sub("<s>", block)


def write(results: dict) -> None:
    """Rewrite the docs block and draw the figure of the symmetric fit."""
    from emasim.analysis.figure_process import DrawHere
    from emasim.analysis.identification_plots import fit_figure

    write_block(DOCS, BLOCK, render(results))
    fit = results["figure"]
    outputs = [n.removeprefix("measured_") for n in fit.traces if n.startswith("measured_")]
    measured = {n: fit.traces[f"measured_{n}"] for n in outputs}
    simulated = {n: fit.traces[f"simulated_{n}"] for n in outputs}
    if FIGURE.exists():
        FIGURE.unlink()  # this script's own figure, redrawn
    DrawHere().save(
        lambda: fit_figure(fit.traces["time_s"], measured, simulated, "EMPS: output-error fit"),
        FIGURE,
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="rewrite the docs block and figure")
    parser.add_argument("--quick", action="store_true", help="(CI) check the data are there")
    args = parser.parse_args()
    if not (EMPS / TRAIN).is_file():
        print(f"no EMPS data at {EMPS}: nothing to measure")
        return 0
    if args.quick:
        print(published())
        return 0
    results = measure()
    print(render(results))
    if args.write:
        write(results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
