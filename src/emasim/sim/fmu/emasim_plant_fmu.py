"""The plant FMU: emasim's compiled drive and load side (lumped rudder or linkage).

Main script of the FMU that :func:`emasim.sim.fmi.export_plant_fmu` builds. The voltages and
loads set before ``doStep(t, dt)`` are held over the step, which runs n = round(dt / step_s)
sub-steps of :func:`emasim.sim.engine.plant_step` (the engine's scheme, exactly). The plant's
packed parameters and initial state come from the resource ``emasim_plant.json``. emasim must
be importable in the Python that runs the FMU.
"""

import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Slave, Real

from emasim.plant import actuator as A
from emasim.signals import Constant, encode
from emasim.sim.core import new_workspace
from emasim.sim.fmi import (
    CONSTANT_VALUE,
    DEFAULT_STEP_S,
    PLANT_ELEMENT_OUTPUTS,
    PLANT_INPUTS,
    PLANT_OUTPUTS,
    PLANT_RESOURCE,
    PLANT_STATE_OUTPUTS,
    plant_substeps,
    read_resource,
    register_step_and_inputs,
    substeps_of,
)
from emasim.version import __version__


class EmasimPlant(Fmi2Slave):
    author = "emasim"
    description = "emasim actuator plant: PMSM, drive train, LuGre, backlash, rudder stage"
    version = __version__
    license = "MIT"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=0.1, step_size=1e-4)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        data = read_resource(self.resources, PLANT_RESOURCE)
        self.p = np.array(data["plant"], dtype=np.float64)
        self.x = np.array(data["initial_state"], dtype=np.float64)
        if self.p.size != A.N_PARAMS or self.x.size != A.N_STATE:
            raise ValueError(f"{PLANT_RESOURCE} does not fit this emasim ({__version__})")
        self.work = new_workspace()
        self.loads = tuple(encode([Constant(value=0.0)]) for _ in range(3))  # motor, rod, rudder
        self.step_s = DEFAULT_STEP_S
        self.ud_V = self.uq_V = self.load_torque_Nm = self.rod_force_N = 0.0
        self.rudder_torque_Nm = 0.0
        register_step_and_inputs(self, PLANT_INPUTS)
        self.outputs = np.zeros(A.N_OUTPUTS)
        states, outputs = A.PLANT.states, A.PLANT.outputs
        getters = {name: self._state_getter(states.index(name)) for name, _ in PLANT_STATE_OUTPUTS}
        for name, _ in PLANT_ELEMENT_OUTPUTS:
            getters[name] = self._output_getter(outputs.index(name))
        for name, text in PLANT_OUTPUTS:
            self.register_variable(
                Real(name, causality=Fmi2Causality.output, description=text, getter=getters[name])
            )

    def _state_getter(self, i: int):
        return lambda: self.x[i]

    def _output_getter(self, i: int):
        def value() -> float:
            A.plant_outputs(self.x, self.p, self.outputs)
            return self.outputs[i]

        return value

    def do_step(self, current_time, step_size):
        n = substeps_of(step_size, self.step_s)
        motor_load, rod_load, rudder_load = self.loads
        motor_load[CONSTANT_VALUE] = self.load_torque_Nm
        rod_load[CONSTANT_VALUE] = self.rod_force_N
        rudder_load[CONSTANT_VALUE] = self.rudder_torque_Nm
        u_d, u_q = self.ud_V, self.uq_V
        plant_substeps(
            current_time, self.x, u_d, u_q, self.p, self.loads, step_size / n, n, self.work
        )
        return bool(np.all(np.isfinite(self.x)))
