"""FMI 2.0 co-simulation: the plant and the linkage as FMUs, and FMUs as co-simulation partners.

Two FMUs are built here with pythonfmu (the slave scripts are in :mod:`emasim.sim.fmu`):

* the **plant** (:func:`export_plant_fmu`): drive and load side (lumped rudder or linkage) on
  the compiled plant. Inputs ``ud_V``, ``uq_V`` (stator voltages), ``load_torque_Nm`` (on the
  motor shaft) and ``rod_force_N`` (external force on the rod), all held over a step; outputs
  the currents, motor angle and speed, bristle state, rod position and velocity, rudder angle,
  drive-train force and motor torque; parameter ``step_s``, the integration sub-step.
  ``doStep(t, dt)`` runs n = round(dt / step_s) sub-steps of :func:`emasim.sim.engine.plant_step`,
  the engine's own scheme, so a master that closes emasim's controllers around the FMU at the
  sample period reproduces the in-process run to the last bit;
* the **mechanism** (:func:`export_mechanism_fmu`): the linkage alone with its rod driven, as in
  :func:`emasim.sim.mechanism.advance`. Inputs ``rod_velocity_m_s`` (held over the step),
  ``rod_position_m`` (the rod extension at the step's start; the FMU integrates it itself when
  the master leaves it alone) and ``rudder_torque_Nm``; outputs ``rudder_angle_rad``,
  ``rod_force_N`` (the linkage's axial push on the rod, the sign of ``advance``'s return value)
  and the 16 linkage states under their trace names; parameter ``step_s``.

The plant's packed parameters and initial state (or the linkage's) travel inside the FMU as a
JSON resource written at export time, so an FMU needs no scenario when it runs. A pythonfmu FMU
runs on the Python of the process that loads it: its binary takes the Python C API from that
process (it does not link libpython), so a Python host such as fmpy works as is, and a tool
that is not Python must have libpython loaded (e.g. ``LD_PRELOAD``). **emasim, numpy and numba
must be importable in that Python**: the FMU carries pythonfmu's Python part, not emasim.

The other direction, :class:`FmuSlave` loads any FMI 2.0 co-simulation FMU with fmpy, and
:class:`FmuMechanism` lets the co-simulation master (:func:`emasim.sim.cosim.cosimulate`) take its
mechanism from an FMU (``solver.mechanism_fmu``).
"""

import contextlib
import importlib
import json
import shutil
import sys
import tempfile
import weakref
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import EmasimError, InputError
from ..jit import njit
from ..plant import actuator as A
from ..plant.elements import linkage as L
from .engine import plant_step

PLANT_RESOURCE = "emasim_plant.json"  # file name of the parameters inside the FMU's resources
MECHANISM_RESOURCE = "emasim_mechanism.json"
PLANT_SCRIPT = "emasim_plant_fmu.py"  # pythonfmu slave scripts in emasim/sim/fmu/
MECHANISM_SCRIPT = "emasim_mechanism_fmu.py"
DEFAULT_STEP_S = 1e-5  # integration sub-step of both FMUs, as the engine's default

# (name, description) of the FMUs' variables; the slave scripts register exactly these
PLANT_INPUTS = (
    ("ud_V", "d-axis stator voltage, held over the step (V)"),
    ("uq_V", "q-axis stator voltage, held over the step (V)"),
    ("load_torque_Nm", "load torque on the motor shaft, held over the step (N m)"),
    ("rod_force_N", "external force on the rod, positive opposing extension, held (N)"),
    (
        "rudder_torque_Nm",
        "load torque on the linkage's rudder shaft, positive opposing "
        "positive deflection, held (N m)",
    ),
)
# the drive's states and the element outputs of the plant (the linkage's are in the
# mechanism FMU), from the elements' declarations
PLANT_STATE_OUTPUTS = tuple(
    (s.name, f"{s.description} ({s.unit})")
    for element in A.ELEMENTS
    if element is not L.LINKAGE
    for s in element.states
)
PLANT_ELEMENT_OUTPUTS = tuple(
    (q.name, f"{q.description} ({q.unit})")
    for element in A.ELEMENTS
    if element is not L.LINKAGE
    for q in element.outputs
)
PLANT_OUTPUTS = PLANT_STATE_OUTPUTS + PLANT_ELEMENT_OUTPUTS
MECHANISM_INPUTS = (
    ("rod_velocity_m_s", "rod extension rate, held over the step (m/s)"),
    ("rod_position_m", "rod extension at the step's start (m); integrated by the FMU if not set"),
    (
        "rudder_torque_Nm",
        "load torque on the rudder shaft, positive opposing positive deflection, held (N m)",
    ),
)
MECHANISM_OUTPUTS = (
    ("rudder_angle_rad", "rudder angle (rad)"),
    ("rod_force_N", "axial force of the linkage on the rod, positive pushing it out (N)"),
    *((name, "linkage state (SI)") for name in L.LINK_STATE_NAMES),
)
STEP_PARAMETER = ("step_s", "integration sub-step (s); a step dt takes round(dt / step_s) of them")


def register_step_and_inputs(slave, inputs) -> None:
    """Register the ``step_s`` parameter and the (name, description) inputs of an FMU slave;
    the slave holds each as an attribute of the same name."""
    from pythonfmu import Fmi2Causality, Fmi2Variability, Real

    name, text = STEP_PARAMETER
    slave.register_variable(
        Real(
            name,
            causality=Fmi2Causality.parameter,
            variability=Fmi2Variability.fixed,
            description=text,
        )
    )
    for name, text in inputs:
        slave.register_variable(Real(name, causality=Fmi2Causality.input, description=text))


CONSTANT_VALUE = 3  # index of the value in a one-term constant signal (emasim.signals.encode)


@njit(cache=True, error_model="numpy")
def plant_substeps(t, x, u_d, u_q, p, loads, h, n, work):
    """n sub-steps of :func:`emasim.sim.engine.plant_step` from t, as the engine runs a tick;
    ``loads`` holds the three encoded loads (motor, rod, rudder: emasim.sim.core.Model)."""
    motor_load, rod_load, rudder_load = loads
    for j in range(n):
        plant_step(t + j * h, x, u_d, u_q, p, motor_load, rod_load, rudder_load, h, work)


def substeps_of(dt: float, step_s: float) -> int:
    """How many sub-steps a step dt takes: round(dt / step_s), at least one."""
    return max(1, round(dt / step_s))


# --- export ---------------------------------------------------------------------------------


def export_plant_fmu(path, plant=None, force: bool = False) -> Path:
    """Write the plant (drive and load side) as an FMI 2.0 co-simulation FMU; return its path.

    ``plant`` is a :class:`~emasim.plant.parameters.PlantParams` (default: the
    ``sea805-linkage`` preset). Its packed parameters and :meth:`initial_state` are stored in
    the FMU (resource ``emasim_plant.json``). The FMU runs emasim's compiled plant in the
    Python of the process that loads it, so emasim (with numpy and numba) must be installed
    there. Variables: see the module docstring (:data:`PLANT_INPUTS`, :data:`PLANT_OUTPUTS`).
    An existing file is replaced only if it is an emasim FMU and ``force`` is set.
    """
    from ..version import __version__

    if plant is None:
        from ..plant.presets import sea805_linkage

        plant = sea805_linkage()
    payload = {
        "format": "emasim-plant-fmu",
        "emasim_version": __version__,
        "plant": plant.pack().tolist(),
        "initial_state": plant.initial_state().tolist(),
        "state_names": list(A.STATE_NAMES),
        "plant_params": plant.model_dump(mode="json"),
    }
    return _build(path, PLANT_SCRIPT, PLANT_RESOURCE, payload, force)


def export_mechanism_fmu(path, plant=None, force: bool = False) -> Path:
    """Write the linkage alone (rod driven) as an FMI 2.0 co-simulation FMU; return its path.

    ``plant`` is a :class:`~emasim.plant.parameters.PlantParams` with a linkage (default: the
    ``sea805-linkage`` preset); its packed linkage parameters are stored in the FMU (resource
    ``emasim_mechanism.json``). The slave wraps :func:`emasim.sim.mechanism.advance` and starts
    in :func:`emasim.plant.elements.linkage.rigid_pose` at the initial ``rod_position_m``. As
    for the plant FMU, emasim must be importable in the Python that runs it.
    """
    from ..version import __version__

    if plant is None:
        from ..plant.presets import sea805_linkage

        plant = sea805_linkage()
    if plant.linkage is None:
        raise InputError(
            "mechanism FMU: the plant has no linkage (use a preset with one: sea805-linkage)"
        )
    payload = {
        "format": "emasim-mechanism-fmu",
        "emasim_version": __version__,
        "linkage": plant.linkage.pack().tolist(),
        "linkage_params": plant.linkage.model_dump(mode="json"),
    }
    return _build(path, MECHANISM_SCRIPT, MECHANISM_RESOURCE, payload, force)


def read_resource(folder, name: str) -> dict:
    """The JSON resource ``name`` in an FMU's resources folder (used by the slave scripts)."""
    return json.loads((Path(folder) / name).read_text())


def is_emasim_fmu(path: Path) -> bool:
    """True for an FMU (zip) that carries one of emasim's resources: one emasim exported."""
    import zipfile

    wanted = {f"resources/{PLANT_RESOURCE}", f"resources/{MECHANISM_RESOURCE}"}
    try:
        with zipfile.ZipFile(path) as archive:
            return bool(wanted & set(archive.namelist()))
    except (OSError, zipfile.BadZipFile):
        return False


def _build(path, script: str, resource_name: str, payload: dict, force: bool) -> Path:
    """Build an FMU from a slave script of emasim.sim.fmu and a JSON resource, then put it in
    place atomically (emasim.output.write_file: never over a file emasim did not write)."""
    FmuBuilder = fmi_extra("pythonfmu", "exporting an FMU").FmuBuilder  # noqa: N806

    from ..output import CLI_HINTS, check_target, write_file

    target = Path(path)
    if target.suffix != ".fmu":
        raise InputError(f"--out {target}: an FMU file name must end in .fmu")
    check_target(target, force, "--out", CLI_HINTS[:1], is_emasim_fmu)
    saved_path = list(sys.path)  # the builder puts the script's folder on sys.path
    with (
        resources.as_file(resources.files("emasim.sim.fmu") / script) as script_file,
        tempfile.TemporaryDirectory(prefix="emasim-fmu-") as tmp,
    ):
        resource = Path(tmp) / resource_name
        resource.write_text(json.dumps(payload))  # floats as repr: they read back exactly
        try:
            built = FmuBuilder.build_FMU(
                script_file, dest=Path(tmp) / "built.fmu", project_files=[resource]
            )
        finally:
            sys.path[:] = saved_path
        complete = with_initial_unknowns(Path(built), Path(tmp) / "complete.fmu")
        write_file(target, complete, force=force, is_ours=is_emasim_fmu, what="--out")
    return target


def with_initial_unknowns(built: Path, out: Path) -> Path:
    """A copy of the FMU ``built`` whose ModelStructure lists every output among its
    InitialUnknowns, which pythonfmu leaves out: an output is computed from the state
    (``initial="calculated"``, FMI 2.0 section 2.2.8), so the standard requires it there;
    no ``dependencies`` attribute means it may depend on every known."""
    import xml.etree.ElementTree as ET  # noqa: N817 - the usual name
    import zipfile

    with zipfile.ZipFile(built) as source, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as dest:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "modelDescription.xml":
                root = ET.fromstring(data)
                structure = root.find("ModelStructure")
                outputs = structure.find("Outputs")
                if outputs is not None and structure.find("InitialUnknowns") is None:
                    unknowns = ET.SubElement(structure, "InitialUnknowns")
                    for unknown in outputs.findall("Unknown"):
                        ET.SubElement(unknowns, "Unknown", index=unknown.get("index"))
                data = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
            dest.writestr(item, data)
    return out


def fmi_extra(module: str, what: str):
    """Import ``module`` of the optional FMI extra (pythonfmu, fmpy), or say in one line how to
    install it (InputError)."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise InputError(
            f"{what} needs emasim's FMI extra ({module} is not installed): "
            "pip install 'emasim[fmi]'"
        ) from None


# --- running FMUs ----------------------------------------------------------------------------


def describe_fmu(path):
    """fmpy's model description of an FMI 2.0 co-simulation FMU; InputError if it is not one."""
    read_model_description = fmi_extra("fmpy", "loading an FMU").read_model_description

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such FMU file")
    try:
        md = read_model_description(str(path))
    except Exception as err:  # fmpy raises whatever the zip, XML or schema check raised
        raise InputError(f"{path}: not a readable FMU ({err})") from None
    if md.fmiVersion != "2.0" or md.coSimulation is None:
        raise InputError(f"{path}: not an FMI 2.0 co-simulation FMU")
    return md


def real_variables(md, causality: str | None = None) -> list[str]:
    """Names of the Real variables of a model description (of one causality, if given)."""
    return [
        v.name
        for v in md.modelVariables
        if v.type == "Real" and (causality is None or v.causality == causality)
    ]


class _Instance:
    """What an open FmuSlave holds outside Python: the instance, the library, the unpacked files
    (kept apart from the FmuSlave so that its finalizer can release them)."""

    def __init__(self, fmu, folder: str):
        self.fmu, self.folder, self.instantiated = fmu, folder, False

    def release(self) -> None:
        try:
            if self.instantiated:
                with contextlib.suppress(Exception):  # an FMU in its error state may refuse
                    self.fmu.terminate()
                self.fmu.freeInstance()  # also unloads the library
            else:
                self.fmu.freeLibrary()
        finally:
            shutil.rmtree(self.folder, ignore_errors=True)


class FmuSlave:
    """An FMI 2.0 co-simulation FMU loaded with fmpy, its Real variables addressed by name.

    Opening instantiates the FMU, sets up the experiment at ``start_time``, enters
    initialisation mode, sets ``start_values`` (name -> value: parameters and inputs) and leaves
    initialisation mode. ``refs`` turns names into value references once; ``set_real``,
    ``get_real`` and ``do_step`` are thin calls of fmpy's. ``close`` (or ``with``) terminates
    and frees the instance and removes the unpacked files; an FmuSlave that is collected
    unclosed is closed then. Raises InputError when the file is not an FMI 2.0 co-simulation
    FMU, and EmasimError when the FMU fails.
    """

    def __init__(self, path, start_values: dict | None = None, start_time: float = 0.0):
        fmi_extra("fmpy", "loading an FMU")
        from fmpy import extract
        from fmpy.fmi2 import FMU2Slave

        self.path = Path(path)
        md = describe_fmu(self.path)
        self.model_description = md
        self._refs = {v.name: v.valueReference for v in md.modelVariables if v.type == "Real"}
        folder = extract(str(self.path))
        self._fmu = FMU2Slave(
            guid=md.guid,
            unzipDirectory=folder,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=md.modelName,
        )
        instance = _Instance(self._fmu, folder)
        self._close = weakref.finalize(self, instance.release)
        try:
            self._fmu.instantiate()
            instance.instantiated = True
            self._fmu.setupExperiment(startTime=start_time)
            self._fmu.enterInitializationMode()
            values = dict(start_values or {})
            if values:
                self.set_real(self.refs(*values), list(values.values()))
            self._fmu.exitInitializationMode()
        except EmasimError:
            self.close()
            raise
        except Exception as err:
            self.close()
            raise EmasimError(f"{self.path}: the FMU failed to initialise: {err}") from None

    def refs(self, *names: str) -> list[int]:
        """Value references of Real variables; InputError naming a missing one."""
        missing = [name for name in names if name not in self._refs]
        if missing:
            raise InputError(f"{self.path}: the FMU has no Real variable '{missing[0]}'")
        return [self._refs[name] for name in names]

    def set_real(self, refs: list[int], values) -> None:
        self._fmu.setReal(refs, values)

    def get_real(self, refs: list[int]) -> list[float]:
        return self._fmu.getReal(refs)

    def do_step(self, t: float, dt: float) -> None:
        """Advance the FMU from communication point t by dt; EmasimError if it fails."""
        try:
            self._fmu.doStep(t, dt)
        except Exception as err:
            raise EmasimError(f"{self.path}: doStep at t = {t:.6g} s failed: {err}") from None

    def close(self) -> None:
        """Terminate and free the instance, unload the library, remove the unpacked files."""
        self._close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class FmuMechanism:
    """The mechanism side of a co-simulation taken from an FMU (``solver.mechanism_fmu``).

    The FMU needs an input ``rod_velocity_m_s`` and outputs ``rudder_angle_rad`` and
    ``rod_force_N`` (the linkage's axial force on the rod, positive pushing it out: the sign
    of :func:`emasim.sim.mechanism.advance`). Used when present: an input ``rod_position_m``
    (the rod extension at the step's start, set every step and at initialisation, so both
    sides agree on the rod position), an input ``rudder_torque_Nm`` (external torque on the
    rudder shaft, positive opposing positive deflection, as the plant FMU's and the
    scenario's ``load.rudder_torque_Nm``), a parameter ``step_s`` (set to the drive's
    sub-step), and
    outputs named as the 16 linkage states (:data:`emasim.plant.elements.linkage.LINK_STATE_NAMES`);
    without them the result's linkage columns are NaN but for the rudder angle and rate
    (see :meth:`read`).
    """

    def __init__(self, path, step_s: float, rod_position_m: float = 0.0):
        try:
            md = describe_fmu(path)
        except InputError as err:
            raise InputError(f"solver.mechanism_fmu: {err}") from None
        inputs, outputs = real_variables(md, "input"), real_variables(md, "output")
        missing = [
            f"{kind} '{name}'"
            for name, kind, have in (
                ("rod_velocity_m_s", "input", inputs),
                ("rudder_angle_rad", "output", outputs),
                ("rod_force_N", "output", outputs),
            )
            if name not in have
        ]
        if missing:
            raise InputError(
                f"solver.mechanism_fmu: {path} lacks the Real {', '.join(missing)} "
                f"(its inputs: {', '.join(inputs) or 'none'}; outputs: "
                f"{', '.join(outputs) or 'none'})"
            )
        self.sets_position = "rod_position_m" in inputs
        self._torque = None
        self.has_states = all(name in outputs for name in L.LINK_STATE_NAMES)
        start = {"rod_position_m": rod_position_m} if self.sets_position else {}
        if "step_s" in real_variables(md, "parameter"):
            start["step_s"] = step_s
        self.fmu = FmuSlave(path, start_values=start)
        self._inputs = self.fmu.refs(
            *(("rod_position_m",) if self.sets_position else ()), "rod_velocity_m_s"
        )
        if "rudder_torque_Nm" in inputs:
            self._torque = self.fmu.refs("rudder_torque_Nm")
        names = L.LINK_STATE_NAMES if self.has_states else ("rudder_angle_rad",)
        self._outputs = self.fmu.refs("rod_force_N", *names)

    def read(self, y: np.ndarray, duration: float | None = None) -> float:
        """Write the FMU's linkage states into y and return its rod force.

        An FMU without the linkage states gives the rudder angle only: y is then NaN but for
        the angle and the rudder rate, its mean over the last step of ``duration`` (0 at the
        start), so that the run's rudder-rate metrics still have a trace.
        """
        values = self.fmu.get_real(self._outputs)
        if self.has_states:
            y[:] = values[1:]
        else:
            angle = values[1]
            rate = 0.0 if duration is None else (angle - y[L.TD]) / duration
            y[:] = np.nan
            y[L.TD], y[L.N_POS + L.TD] = angle, rate
        return values[0]

    def advance(
        self, y: np.ndarray, t: float, s0: float, v: float, duration: float, load: float = 0.0
    ) -> float:
        """The FMU over [t, t + duration] with the rod at s0 + v (t' - t) and a ``load`` torque
        on the rudder shaft (positive opposing positive deflection; refused by an FMU without
        that input, unless 0); y receives its states; returns the axial force of the linkage on
        the rod at the end, as ``advance``."""
        if self._torque is not None:
            self.fmu.set_real(self._torque, [load])
        elif load != 0.0:
            raise InputError(f"{self.fmu.path}: the FMU has no input rudder_torque_Nm")
        self.fmu.set_real(self._inputs, [s0, v] if self.sets_position else [v])
        self.fmu.do_step(t, duration)
        return self.read(y, duration)

    def close(self) -> None:
        self.fmu.close()
