"""The mechanism FMU: emasim's clearance-joint linkage alone, its rod driven.

Main script of the FMU that :func:`emasim.sim.fmi.export_mechanism_fmu` builds. Over
``doStep(t, dt)`` the rod extension is s(t') = s0 + v (t' - t), with s0 = ``rod_position_m``
and v = ``rod_velocity_m_s``; the 16 linkage states take n = round(dt / step_s) RK4 steps of
:func:`emasim.sim.mechanism.advance`, which also gives ``rod_force_N``, the linkage's axial push
on the rod. At initialisation the linkage takes its rigid pose
(:func:`emasim.plant.elements.linkage.rigid_pose`) at ``rod_position_m``. The packed linkage
parameters come from the resource ``emasim_mechanism.json``. emasim must be importable in the
Python that runs the FMU.
"""

import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Slave, Real

from emasim.plant.elements import linkage as L
from emasim.sim.fmi import (
    DEFAULT_STEP_S,
    MECHANISM_INPUTS,
    MECHANISM_OUTPUTS,
    MECHANISM_RESOURCE,
    read_resource,
    register_step_and_inputs,
    substeps_of,
)
from emasim.sim.mechanism import advance
from emasim.version import __version__


class EmasimMechanism(Fmi2Slave):
    author = "emasim"
    description = "emasim control-surface linkage with clearance joints, rod velocity driven"
    version = __version__
    license = "MIT"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=0.1, step_size=1e-3)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.q = np.array(read_resource(self.resources, MECHANISM_RESOURCE)["linkage"])
        if self.q.size != L.N_LINK_PARAMS:
            raise ValueError(f"{MECHANISM_RESOURCE} does not fit this emasim ({__version__})")
        self.hinges = np.zeros((L.N_HINGES, 2))
        self.step_s = DEFAULT_STEP_S
        self.rod_position_m = self.rod_velocity_m_s = self.rudder_torque_Nm = 0.0
        self.y = L.rigid_pose(0.0, self.q)
        self.rod_force_N = 0.0
        register_step_and_inputs(self, MECHANISM_INPUTS)
        getters = {"rudder_angle_rad": lambda: self.y[L.TD], "rod_force_N": None}
        for i, state in enumerate(L.LINK_STATE_NAMES):
            getters[state] = lambda i=i: self.y[i]
        for name, text in MECHANISM_OUTPUTS:
            self.register_variable(
                Real(name, causality=Fmi2Causality.output, description=text, getter=getters[name])
            )

    def exit_initialization_mode(self):
        self.y = L.rigid_pose(self.rod_position_m, self.q)
        self.rod_force_N = L.linkage_rhs(
            self.y,
            self.rod_position_m,
            self.rod_velocity_m_s,
            -self.rudder_torque_Nm,  # a load: positive opposes positive deflection
            self.q,
            np.empty(L.N_LINK),
            self.hinges,
        )

    def do_step(self, current_time, step_size):
        s0, v = self.rod_position_m, self.rod_velocity_m_s
        self.rod_force_N = advance(
            self.y,
            s0,
            v,
            step_size,
            substeps_of(step_size, self.step_s),
            -self.rudder_torque_Nm,
            self.q,
            self.hinges,
        )
        self.rod_position_m = s0 + v * step_size
        return bool(np.all(np.isfinite(self.y)))
