"""Export the plant as an FMI 2.0 co-simulation FMU and drive it under fmpy, as a Simulink or
Modelica user would: a constant q-axis voltage for 20 ms, the motor speed read back.

    python examples/export_fmu.py
"""

from fmpy import simulate_fmu

from emasim.plant.presets import sea805
from emasim.sim.fmi import export_plant_fmu

path = export_plant_fmu("emasim-plant.fmu", sea805())
result = simulate_fmu(
    str(path),
    stop_time=0.02,
    output_interval=1e-3,
    start_values={"uq_V": 20.0},
    output=["motor_speed_rad_s", "iq_A"],
)
print(
    f"{path}: after 20 ms at uq = 20 V the motor turns at {result['motor_speed_rad_s'][-1]:.1f} "
    f"rad/s, iq = {result['iq_A'][-1]:.2f} A"
)
