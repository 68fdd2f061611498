"""The trace layout: every column a run can record, in order, with its unit.

Time, the plant's states, the loops' signals, the elements' outputs, the loads, and the
measurements the controllers saw. The compiled loop (emasim.sim.engine.record) fills a full
row by these indices and stores the columns a run keeps (emasim.sim.setup.Setup.kept_columns);
scenarios check ``solver.record_signals`` against these names, without loading the core.
"""

from ..plant import actuator as A
from ..plant.element import Layout, Quantity

CONTROL_COLUMNS = (
    Quantity("speed_ref_rad_s", "rad/s", "speed command (NaN when the position loop commands iq)"),
    Quantity("iq_ref_A", "A", "q-axis current command"),
    Quantity("position_ref_m", "m", "rod position reference (NaN in a speed-loop run)"),
    Quantity("ud_V", "V", "d-axis stator voltage command, limited by the inverter"),
    Quantity("uq_V", "V", "q-axis stator voltage command, limited by the inverter"),
    Quantity(
        "current_limit_A", "A", "the drive's current limit in force (emasim.plant.elements.ratings)"
    ),
    Quantity(
        "limit_flags",
        "1",
        "the drive's limits the commands sat at: LIMIT_* bits of emasim.interface",
    ),
)
LOAD_COLUMNS = (
    Quantity("load_torque_Nm", "N m", "external load torque on the motor shaft"),
    Quantity("rod_load_N", "N", "external force on the rod, positive opposing extension"),
    Quantity("rudder_load_Nm", "N m", "rudder load T(t), opposing positive deflection"),
)
MEASURED_COLUMNS = (
    Quantity("measured_speed_rad_s", "rad/s", "speed sensor reading"),
    Quantity("measured_position_m", "m", "the position loop's reading: rod sensor, or rudder"),
    Quantity("measured_rudder_rad", "rad", "rudder encoder reading"),
    Quantity("measured_angle_rad", "rad", "motor encoder reading"),
    Quantity("measured_rod_position_m", "m", "rod sensor reading (the rod's extension)"),
    Quantity("measured_iq_A", "A", "q-axis current reading"),
    Quantity("measured_force_N", "N", "rod force sensor reading"),
)
TRACE = Layout(
    (
        Quantity("t_s", "s", "time"),
        *A.PLANT.states.quantities,
        *CONTROL_COLUMNS,
        *A.PLANT.outputs.quantities,
        *LOAD_COLUMNS,
        *MEASURED_COLUMNS,
    )
)
TRACE_COLUMNS = TRACE.names
N_COLUMNS = len(TRACE)
C_STATE = TRACE.index(A.STATE_NAMES[0])
C_SPEED_REF = TRACE.index("speed_ref_rad_s")
C_IQ_REF = TRACE.index("iq_ref_A")
C_POSITION_REF = TRACE.index("position_ref_m")
C_UD = TRACE.index("ud_V")
C_UQ = TRACE.index("uq_V")
C_CURRENT_LIMIT = TRACE.index("current_limit_A")
C_LIMIT_FLAGS = TRACE.index("limit_flags")
C_OUTPUTS = TRACE.index(A.PLANT.outputs.names[0])
C_MOTOR_LOAD = TRACE.index("load_torque_Nm")
C_ROD_LOAD = TRACE.index("rod_load_N")
C_RUDDER_LOAD = TRACE.index("rudder_load_Nm")
C_MEASURED_SPEED = TRACE.index("measured_speed_rad_s")
C_MEASURED_POSITION = TRACE.index("measured_position_m")
C_MEASURED_RUDDER = TRACE.index("measured_rudder_rad")
C_MEASURED_ANGLE = TRACE.index("measured_angle_rad")
C_MEASURED_ROD = TRACE.index("measured_rod_position_m")
C_MEASURED_IQ = TRACE.index("measured_iq_A")
C_MEASURED_FORCE = TRACE.index("measured_force_N")
