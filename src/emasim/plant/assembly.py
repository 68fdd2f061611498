"""The plant's compiled functions, generated from its elements' declarations.

Every element declares its behaviour (emasim.plant.element): the bodies it owns, the nodes
that follow others, its couplings and laws, the forces they put on nodes, the rates of its
states and the values of its outputs. :func:`generate` writes, from those declarations alone,
the source of a module of compiled functions:

* ``rhs(x, u_d, u_q, t_load, f_load, t_rudder, p, dx, hinges)``: every node's motion (in
  dependency order: a body's states, or the node an absent body merges into, or a derived
  node's motion law), then each element's couplings and laws (a present element's; an absent
  one's results are 0 and its rates 0), then every node's force, summed and resolved against
  the dependencies in reverse: a body accelerates as force / mass, an absent body passes its
  force to its alias, a derived node folds its force onto the nodes it follows. With the
  plant's ``hold`` parameter at its held value the mechanism elements' rates are 0 (a
  co-simulation integrates them apart). It returns the derived node's ``exchange`` result.
  A derived node's motion runs only where a present element reads it (:func:`_lazy`).
* ``plant_outputs(x, p, out)``: every element output, NaN for an absent element's, and
  ``output_<name>(x, p)`` for each alone (what the sensors read), each computing only what
  its output needs (:func:`_prune`).
* ``active_states(p)``: the states that move, up to the end of the last present element.

Given the names of elements known to be ``absent``, the module is that of every plant without
them: their terms are left out and their results, rates and motions written as their absent
values, with no presence test, and ``applies(p)`` tells whether a plant is such a plant. It
holds ``rhs`` and ``active_states`` only (emasim.plant.actuator.DRIVE: the presence tests of
the absent elements cost a third of the lumped plant's right-hand side).

Every index is a literal in the generated source: nothing is kept by hand. The source is
written to the keyed numba cache folder (emasim.numba_cache), so numba caches its machine code
as it does any module's, and imported from there.
"""

import graphlib
import hashlib
import importlib.util
import os
import re
import sys
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..numba_cache import configured_folder
from .element import GROUND, Coupling, Law, PlantLayout

INPUTS = ("u_d", "u_q", "t_load", "f_load", "t_rudder")
INDENT = "    "


IDENTIFIER = re.compile(r"\b(?:\w+__\w+|(?:fold|f|x|v)_\w+)\b")


@dataclass
class _Statement:
    """Lines of source, what they define and need, and the presence they run under: where
    ``guard`` fails, ``absent`` runs instead. ``sink`` marks a statement kept for its effect."""

    lines: list[str]
    provides: set[str] = field(default_factory=set)
    guard: str | None = None
    absent: list[str] = field(default_factory=list)
    sink: bool = False
    kind: str = ""  # "derived" or "alias": a node's motion (see _lazy)

    @property
    def needs(self) -> set[str]:
        used = set(IDENTIFIER.findall("\n".join(self.lines + self.absent)))
        return used - self.provides


ABSENT = "False"  # the presence condition of an element known to be absent


class _Plant:
    """What the generator knows of a plant: its nodes, how each token binds and which
    elements are known to be absent."""

    def __init__(self, plant: PlantLayout, hold: tuple[str, float] | None, absent=frozenset()):
        self.plant, self.hold, self.absent = plant, hold, absent
        self.bodies, self.derived, self.port = plant.bodies, plant.derived, plant.port
        self.functions: dict[object, str] = {}

    def name_of(self, function) -> str:
        """The generated module's name for a compiled function (imported once)."""
        return self.functions.setdefault(function, f"_f{len(self.functions)}")

    def elements_absent(self) -> list:
        return [e for e in self.plant.elements if e.name in self.absent]

    def present(self, element) -> str | None:
        """The condition that the element is present: None for one always there, ABSENT for
        one known to be absent."""
        if element.presence is None:
            return None
        if element.name in self.absent:
            return ABSENT
        return f"p[{self.plant.params.index(element.presence)}] != 0.0"

    def bind(self, token: str, element) -> str:
        """The source expression of an argument token (emasim.plant.element.Law)."""
        layout = self.plant
        if token.startswith("-"):
            return f"-{self.bind(token[1:], element)}"
        try:
            return repr(float(token))
        except ValueError:
            pass
        if token.startswith("in."):
            if token[3:] not in INPUTS:
                raise ValueError(f"{element.name}: no input '{token}'")
            return token[3:]
        if token in ("hinges", "x", "dx", "p"):
            return token
        if token.startswith(("x0[", "p0[")):  # where an element's states or parameters start
            name = token[3:-1]
            offsets = layout.state_offset if token[0] == "x" else layout.param_offset
            return str(offsets[name])
        if token.startswith(("x.", "p.")):
            vector = layout.states if token[0] == "x" else layout.params
            return f"{token[0]}[{vector.index(token[2:])}]"
        if token.endswith("]"):
            vector, name = token[:-1].split("[")
            other = next(e for e in layout.elements if e.name == name)
            if vector == "p":
                start, size = layout.param_offset[name], len(other.params)
            else:
                start, size = layout.state_offset[name], len(other.states)
            return f"{vector}[{start}:{start + size}]"
        if "." in token:
            port, what = token.rsplit(".", 1)
            if what in ("x", "v", "f", "fold"):
                return f"{what}_{self.port(port)}"
            return f"{port}__{what}"  # another element's result
        return f"{element.name}__{token}"

    def call(self, law: Law, element, results: tuple[str, ...]) -> str:
        """``results = function(arguments)``, the function imported once."""
        function = self.name_of(law.function)
        args = ", ".join(self.bind(a, element) for a in law.args)
        return f"{', '.join(results)} = {function}({args})"

    def own(self, element, names) -> tuple[str, ...]:
        return tuple(f"{element.name}__{name}" for name in names)


def _node_order(g: _Plant) -> list[str]:
    """Every node after the nodes its motion depends on."""
    graph = {GROUND: set()}
    for node, (_, body) in g.bodies.items():
        graph[node] = {g.port(body.alias)} if body.alias else set()
    for node, (_, derived) in g.derived.items():
        graph[node] = {
            g.port(a.rsplit(".", 1)[0]) for a in derived.motion.args if a.endswith((".x", ".v"))
        }
    return list(graphlib.TopologicalSorter(graph).static_order())


def _motions(g: _Plant, order: list[str]) -> list[_Statement]:
    states = g.plant.states
    out = [_Statement(["x_ground = 0.0", "v_ground = 0.0"], {"x_ground", "v_ground"})]
    for node in order:
        provides = {f"x_{node}", f"v_{node}"}
        if node in g.bodies:
            element, body = g.bodies[node]
            own = [
                f"x_{node} = x[{states.index(body.position)}]",
                f"v_{node} = x[{states.index(body.velocity)}]",
            ]
            alias = g.port(body.alias) if body.alias else None
            merged = [f"x_{node} = x_{alias}", f"v_{node} = v_{alias}"] if alias else []
            kind = "alias" if alias else ""
            out.append(_Statement(own, provides, g.present(element), merged, kind=kind))
        elif node in g.derived:
            element, derived = g.derived[node]
            line = g.call(derived.motion, element, (f"x_{node}", f"v_{node}"))
            out.append(_Statement([line], provides, kind="derived"))
    return out


def _coupling(g: _Plant, c: Coupling, element) -> str:
    a, b = g.port(c.a), g.port(c.b)
    dx = f"x_{a} - x_{b}" if a != GROUND else f"-x_{b}"
    dv = f"v_{a} - v_{b}" if a != GROUND else f"-v_{b}"
    function = g.name_of(c.law)
    params = "".join(f", {g.bind('p.' + q, element)}" for q in c.params)
    return f"{element.name}__{c.result} = {function}({dx}, {dv}{params})"


def _uses_fold(law: Law) -> bool:
    return any(a.endswith(".fold") for a in law.args)


def _laws(g: _Plant, sink: str, fold_laws: bool) -> list[_Statement]:
    """Each element's couplings and laws (those that need no fold, or only those that do),
    then its rates (sink "rates") or values (sink "values"); an absent element's results are
    0, its rates 0, its values NaN."""
    layout, out = g.plant, []
    for element in layout.elements:
        present = g.present(element)
        if not fold_laws:
            for c in element.couplings:
                out.append(
                    _Statement(
                        [_coupling(g, c, element)],
                        {f"{element.name}__{c.result}"},
                        present,
                        [f"{element.name}__{c.result} = 0.0"],
                    )
                )
        for law in element.laws:
            if _uses_fold(law) != fold_laws:
                continue
            results = g.own(element, law.results)
            guard = None if law.always else present
            out.append(
                _Statement(
                    [g.call(law, element, results)],
                    set(results),
                    guard,
                    [f"{r} = 0.0" for r in results],
                )
            )
        if sink == "rates" and not fold_laws:
            for state, token in element.rates:
                i = layout.states.index(state)
                out.append(
                    _Statement(
                        [f"dx[{i}] = {g.bind(token, element)}"],
                        set(),
                        present,
                        [f"dx[{i}] = 0.0"],
                        sink=True,
                    )
                )
        if sink == "values" and fold_laws:
            for name, token in element.values:
                always = any(token in law.results for law in element.laws if law.always)
                guard = None if always or token.endswith((".x", ".v")) else present
                i = layout.outputs.index(name)
                out.append(
                    _Statement(
                        [f"out[{i}] = {g.bind(token, element)}"],
                        set(),
                        guard,
                        [f"out[{i}] = np.nan"],
                        sink=True,
                    )
                )
    return out


def _terms(g: _Plant) -> dict[str, list[str]]:
    """node -> the signed source terms of the forces on it, in element order."""
    terms = {node: [] for node in (*g.bodies, *g.derived, GROUND)}
    for element in g.plant.elements:
        for c in element.couplings:
            force = f"{element.name}__{c.result}"
            terms[g.port(c.b)].append(f"+ {force}")
            terms[g.port(c.a)].append(f"- {force}")
        for node, signed in element.forces:
            sign, token = signed[0], signed[1:]
            terms[g.port(node)].append(f"{sign} {g.bind(token, element)}")
    return terms


def _resolve(g: _Plant, order: list[str], rates: bool) -> tuple[list[_Statement], str | None]:
    """Every node's force, leaves first: a body accelerates (with ``rates``) or passes its
    force on, a derived node folds it onto the nodes it follows."""
    layout, terms, out, exchange = g.plant, _terms(g), [], None
    accelerations = {node: [] for node in terms}
    for node in reversed(order):
        if node == GROUND:
            continue
        if node in g.bodies:
            terms[node] = _ordered(terms[node], g.bodies[node][1].order)
        summed = " ".join(terms[node]).lstrip("+ ") or "0.0"
        out.append(_Statement([f"f_{node} = {summed}"], {f"f_{node}"}))
        if node in g.derived:
            element, derived = g.derived[node]
            results = g.own(element, derived.fold.results)
            call = g.call(derived.fold, element, results)
            out.append(_Statement([call], set(results), sink=rates))
            for target, result in zip(derived.onto, results, strict=True):
                if target.endswith(".a"):
                    accelerations[g.port(target[:-2])].append(f" + {result}")
                else:
                    terms[g.port(target)].append(f"+ {result}")
            if derived.exchange:
                exchange = f"{element.name}__{derived.exchange}"
            continue
        element, body = g.bodies[node]
        position = layout.states.index(body.position)
        velocity = layout.states.index(body.velocity)
        accelerate = [
            f"dx[{position}] = v_{node}",
            f"dx[{velocity}] = f_{node} / p[{layout.params.index(body.mass)}]"
            + "".join(accelerations[node]),
        ]
        present = g.present(element)
        if rates:
            out.append(
                _Statement(
                    accelerate,
                    set(),
                    present,
                    [f"dx[{position}] = dx[{velocity}] = 0.0"],
                    sink=True,
                )
            )
        if body.alias:
            out.append(
                _Statement(
                    [f"fold_{node} = 0.0"], {f"fold_{node}"}, present, [f"fold_{node} = f_{node}"]
                )
            )
            terms[g.port(body.alias)].append(f"+ fold_{node}")
    return out, exchange


def _ordered(terms: list[str], order: tuple[str, ...]) -> list[str]:
    """The terms of a body's equation, those named in ``order`` first (an element's name
    names all its terms, or a term by its source name), the rest as they came."""

    def rank(term: str) -> int:
        name = term[2:]
        for i, wanted in enumerate(order):
            if name == wanted or name.startswith(f"{wanted}__"):
                return i
        return len(order)

    return sorted(terms, key=rank)


def _lazy(statements: list[_Statement]) -> list[_Statement]:
    """The statements, a derived node's motion computed only where a present element uses it
    (the rocker arm's angle of a plant without rudder stops, shaft or load motor is never
    needed): when every statement that reads the motion runs under a presence condition
    (through the nodes that merge into it while absent), the motion runs under their union."""

    def conditions(names: set[str], after: int) -> set[str] | None:
        found = set()
        for statement in statements[after + 1 :]:
            if not statement.needs & names:
                continue
            if (
                statement.kind == "alias"
                and not set(IDENTIFIER.findall("\n".join(statement.lines))) & names
            ):  # only while its body is absent does the node take this motion
                deeper = conditions(statement.provides, statements.index(statement))
                if deeper is None:
                    return None
                found |= deeper
            elif statement.guard is None:
                return None
            else:
                found.add(statement.guard)
        return found

    out = []
    for i, statement in enumerate(statements):
        guards = conditions(statement.provides, i) if statement.kind == "derived" else None
        if guards:
            absent = [f"{name} = 0.0" for name in sorted(statement.provides)]
            statement = replace(statement, guard=" or ".join(sorted(guards)), absent=absent)
        out.append(statement)
    return out


def _fixed(statements: list[_Statement]) -> list[_Statement]:
    """The statements of an absent element (guard ABSENT) replaced by their absent lines."""
    return [
        replace(s, lines=s.absent, guard=None, absent=[]) if s.guard == ABSENT else s
        for s in statements
    ]


def _prune(statements: list[_Statement]) -> list[_Statement]:
    """The sinks and what they need, in their order."""
    needed, kept = set(), []
    for statement in reversed(statements):
        if statement.sink or statement.provides & needed:
            kept.append(statement)
            needed |= statement.needs
    return kept[::-1]


def _emit(statements: list[_Statement]) -> list[str]:
    """Source lines, statements of one presence grouped under one if/else."""
    lines, i = [], 0
    while i < len(statements):
        guard = statements[i].guard
        group = [statements[i]]
        while i + len(group) < len(statements) and statements[i + len(group)].guard == guard:
            group.append(statements[i + len(group)])
        i += len(group)
        if guard is None:
            lines += [INDENT + line for s in group for line in s.lines]
            continue
        lines.append(f"{INDENT}if {guard}:")
        lines += [2 * INDENT + line for s in group for line in s.lines]
        absent = [line for s in group for line in s.absent]
        if absent:
            lines.append(f"{INDENT}else:")
            lines += [2 * INDENT + line for line in absent]
    return lines


def _held(g: _Plant) -> list[_Statement]:
    """With the plant held, the mechanism's states do not move in this right-hand side."""
    layout = g.plant
    first = [layout.state_offset[e.name] for e in layout.elements if e.mechanism and e.states]
    if g.hold is None or not first:
        return []
    name, value = g.hold
    return [
        _Statement(
            [
                f"if p[{layout.params.index(name)}] == {float(value)!r}:",
                f"    for i in range({min(first)}, {len(layout.states)}):",
                "        dx[i] = 0.0",
            ],
            sink=True,
        )
    ]


def _active_states(g: _Plant) -> list[str]:
    layout = g.plant
    lines = []
    held = "" if g.hold is None else f"p[{layout.params.index(g.hold[0])}] != {float(g.hold[1])!r}"
    always_end = 0
    for element in reversed(layout.elements):
        present = g.present(element)
        if not element.states or present == ABSENT:
            continue
        end = layout.state_offset[element.name] + len(element.states)
        if element.mechanism and held:
            present = held if present is None else f"{present} and {held}"
        elif present is None:
            always_end = max(always_end, end)
            continue
        lines.append(f"    if {present}:\n        return {end}")
    return [*lines, f"    return {always_end}"]


HEADER = '''"""Generated by emasim.plant.assembly from the plant's elements: do not edit."""

import numpy as np

from emasim.jit import njit

'''
DECORATOR = '@njit(cache=True, inline="always", error_model="numpy")'


def _without_inputs(lines: list[str]) -> list[str]:
    """An outputs function's lines, the inputs it reads (none of the outputs needs one, but
    a law may take one) set to 0 first."""
    used = [name for name in INPUTS if re.search(rf"\b{name}\b", "\n".join(lines))]
    return ([f"    {' = '.join(used)} = 0.0"] if used else []) + lines


def _function(signature: str, doc: str, lines: list[str], inline: bool = True) -> list[str]:
    decorator = DECORATOR if inline else DECORATOR.replace(', inline="always"', "")
    return ["", "", decorator, f"def {signature}:", f'    """{doc}"""', *lines]


def _outputs(g: _Plant, motions: list[_Statement], order: list[str]) -> list[str]:
    """The source of ``plant_outputs`` and of each ``output_<name>``."""
    outputs = [
        *motions,
        *_laws(g, "values", False),
        *_resolve(g, order, rates=False)[0],
        *_laws(g, "values", True),
    ]
    functions = _function(
        "plant_outputs(x, p, out)",
        "Every element output of x (emasim.plant.assembly).",
        _without_inputs(_emit(_prune(outputs))),
        inline=False,
    )
    for i, name in enumerate(g.plant.outputs.names):
        one = [s for s in outputs if not s.sink or s.lines[0].startswith(f"out[{i}] =")]
        body = [line.replace(f"out[{i}] =", "value =") for line in _emit(_prune(one))]
        functions += _function(
            f"output_{name}(x, p)",
            f"The output {name} of x alone.",
            [*_without_inputs(body), "    return value"],
        )
    return functions


def generate(
    plant: PlantLayout, hold: tuple[str, float] | None = None, absent: frozenset = frozenset()
) -> str:
    """The source of the plant's compiled module, or of that of every plant without the
    elements ``absent`` (module docstring)."""
    g = _Plant(plant, hold, absent)
    if any(e.presence is None for e in g.elements_absent()):
        raise ValueError(f"{sorted(absent)}: an element always present cannot be absent")
    order = _node_order(g)
    motions = _fixed(_motions(g, order))
    resolved, exchange = _resolve(g, order, rates=True)
    rhs = _lazy(_prune(_fixed([*motions, *_laws(g, "rates", False), *resolved, *_held(g)])))
    functions = _function(
        f"rhs(x, {', '.join(INPUTS)}, p, dx, hinges)",
        "dx/dt of the plant (emasim.plant.assembly); returns the exchanged force.",
        [*_emit(rhs), f"    return {exchange or '0.0'}"],
    )
    functions += _function(
        "active_states(p)", "How many states move (emasim.plant.assembly).", _active_states(g)
    )
    if absent:
        tests = [f"p[{plant.params.index(e.presence)}] == 0.0" for e in g.elements_absent()]
        functions += _function(
            "applies(p)",
            "Whether the plant of p has none of the absent elements.",
            [f"    return {' and '.join(tests)}"],
        )
    else:
        functions += _outputs(g, motions, order)
    imports = [
        f"from {f.__module__} import {f.__name__} as {alias}" for f, alias in g.functions.items()
    ]
    return HEADER + "\n".join(imports) + "\n" + "\n".join(functions) + "\n"


def _folder() -> Path:
    """Where generated modules go: the keyed numba cache (so their machine code is cached)."""
    folder = configured_folder() / "generated"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        return folder
    except OSError:
        return Path(tempfile.mkdtemp(prefix="emasim-generated-"))


def load(plant: PlantLayout, hold: tuple[str, float] | None = None, absent=frozenset()):
    """The plant's generated module (of the plants without ``absent``), written (once per
    source) and imported."""
    source = generate(plant, hold, absent)
    digest = hashlib.sha256(source.encode()).hexdigest()[:16]
    path = _folder() / f"plant_{digest}.py"
    if not path.exists() or path.read_text() != source:
        fd, temporary = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        try:
            with os.fdopen(fd, "w") as handle:
                handle.write(source)
            os.replace(temporary, path)  # one writer's identical text replaces another's
        finally:
            Path(temporary).unlink(missing_ok=True)  # ours, left only if the write failed
    name = f"emasim_generated_plant_{digest}"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # numba's cache finds the module of cached code by its name
    spec.loader.exec_module(module)
    return module
