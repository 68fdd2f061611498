"""Export the plant as an FMI 2.0 co-simulation FMU and drive it under fmpy, as a Simulink or
Modelica user would: a constant q-axis voltage for 20 ms, the motor speed read back.

    python examples/export_fmu.py [FIGURE_FOLDER]

It draws the motor speed and the q-axis current against time into
FIGURE_FOLDER/fmu-response.png (default: the current folder).
"""

import sys
from pathlib import Path

from fmpy import simulate_fmu
from matplotlib.figure import Figure  # files only: no window, no pyplot

from emasim.plant.presets import sea805
from emasim.sim.fmi import export_plant_fmu

# force: a second run replaces the FMU the first wrote (only an emasim FMU is ever replaced)
path = export_plant_fmu("emasim-plant.fmu", sea805(), force=True)
result = simulate_fmu(
    str(path),
    stop_time=0.02,
    output_interval=2e-4,
    start_values={"uq_V": 20.0},
    output=["motor_speed_rad_s", "iq_A"],
)
print(
    f"{path}: after 20 ms at uq = 20 V the motor turns at {result['motor_speed_rad_s'][-1]:.1f} "
    f"rad/s, iq = {result['iq_A'][-1]:.2f} A"
)

fig = Figure(figsize=(6, 4.5), layout="constrained")
speed, current = fig.subplots(2, 1, sharex=True)
t_ms = 1e3 * result["time"]
speed.plot(t_ms, result["motor_speed_rad_s"])
current.plot(t_ms, result["iq_A"], color="C1")
speed.set_ylabel("motor speed (rad/s)")
current.set_ylabel("q-axis current (A)")
current.set_xlabel("time (ms)")
speed.set_title(f"{path.name} under fmpy: uq = 20 V from rest")
for ax in (speed, current):
    ax.grid(True, alpha=0.3)
folder = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
folder.mkdir(parents=True, exist_ok=True)
fig.savefig(folder / "fmu-response.png", dpi=120)
