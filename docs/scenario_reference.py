"""The scenario file's reference page, generated from its pydantic models.

    python docs/scenario_reference.py      # rewrite docs/scenario-reference.md

Every section of a scenario file (emasim.scenarios.schema.Scenario), and of an axis scenario
(emasim.scenarios.axis_scenario.AxisScenario), is a model; each key's type, default, allowed
range and description come from its field. ``tests/test_docs.py`` checks that the page is
this script's output, so it cannot drift from the code.
"""

import sys
import types
import typing
from pathlib import Path

import annotated_types
from pydantic import BaseModel
from pydantic_core import PydanticUndefined

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "scenario-reference.md"
sys.path.insert(0, str(ROOT / "src"))

BOUNDS = {  # constraint -> (symbol, its attribute)
    annotated_types.Ge: (">=", "ge"),
    annotated_types.Gt: (">", "gt"),
    annotated_types.Le: ("<=", "le"),
    annotated_types.Lt: ("<", "lt"),
}
INTRO = """# Scenario file reference

Generated from the scenario schema's models by `docs/scenario_reference.py` (a test keeps this
page equal to its output). Every key is checked when a scenario is read: an unknown key, a
value of the wrong type, NaN or infinity, or one outside its range is refused in one line
naming the key and the range. A section given as a string names a preset
(`plant = "sea805-bench"`, `sensors = "bench-digital"`) whose fields the table's keys
override; `emasim list` shows the presets and the controllers. Units are in the keys' names.
"""


def _models(annotation) -> list[type[BaseModel]]:
    """The BaseModel classes inside an annotation (``X``, ``X | None``, ``list[X]``, unions)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    found = []
    for arg in typing.get_args(annotation):
        for model in _models(arg):
            if model not in found:
                found.append(model)
    return found


def _type(annotation) -> str:
    """A short name of a type: ``float``, ``"a" | "b"``, ``list of Step | Ramp``, ..."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Literal:
        return " | ".join(f'`"{a}"`' if isinstance(a, str) else f"`{a}`" for a in args)
    if origin is typing.Annotated:
        return _type(args[0])
    if origin in (typing.Union, types.UnionType):
        return " | ".join(_type(a) for a in args if a is not type(None)) + (
            " or unset" if type(None) in args else ""
        )
    if origin in (list, tuple):
        inner = ", ".join(_type(a) for a in args if a is not Ellipsis)
        return f"list of {inner}" if inner else "list"
    if origin is dict:
        return f"table of {_type(args[1])}" if len(args) == 2 else "table"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return f"section `{annotation.__name__}`"
    return getattr(annotation, "__name__", str(annotation)).replace("NoneType", "unset")


def _bound(item) -> str | None:
    for kind, (symbol, attribute) in BOUNDS.items():
        if isinstance(item, kind):
            return f"{symbol} {getattr(item, attribute)}"
    return None


def _allowed(field) -> str:
    parts = [b for b in map(_bound, field.metadata) if b]
    text = str in (field.annotation, *typing.get_args(field.annotation))
    what = "characters" if text else "items"
    for item in field.metadata:
        if isinstance(item, annotated_types.MinLen):
            parts.append(f"at least {item.min_length} {what}")
        if isinstance(item, annotated_types.MaxLen):
            parts.append(f"at most {item.max_length} {what}")
    for arg in typing.get_args(field.annotation):  # numbers(count, ...) and the like
        parts += [f"each {b}" for b in map(_bound, getattr(arg, "__metadata__", ())) if b]
    return ", ".join(parts)


def _default(field) -> str:
    if field.is_required():
        return "required"
    value = field.default
    if value is PydanticUndefined:
        return "computed"
    if isinstance(value, BaseModel):
        return "its section's defaults"
    if value in ([], {}, ()):
        return "empty"
    return f"`{value!r}`" if not isinstance(value, str) else f'`"{value}"`'


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def section(model: type[BaseModel], path: str, seen: set, out: list[str]) -> None:
    """The table of ``model`` at ``path`` (the first path a model is met at: a table's type
    column names the section of each model it holds), then the tables of the models it
    holds."""
    if model in seen:
        return
    seen.add(model)
    doc = " ".join((model.__doc__ or "").split("\n\n")[0].split())
    out += [f"## `{path}`: `{model.__name__}`", "", doc, ""]
    out += ["| key | type | default | allowed | description |"]
    out.append("|---|---|---|---|---|")
    nested = []
    for name, field in model.model_fields.items():
        out.append(
            f"| `{name}` | {_cell(_type(field.annotation))} | {_cell(_default(field))} | "
            f"{_cell(_allowed(field))} | {_cell(field.description or '')} |"
        )
        for inner in _models(field.annotation):
            tag = inner.model_fields.get("name") or inner.model_fields.get("type")
            choice = typing.get_args(tag.annotation) if tag is not None else ()
            label = f" ({tag_name(inner)} = {', '.join(repr(c) for c in choice)})" if choice else ""
            nested.append((inner, f"{path}.{name}{label}"))
    out.append("")
    for inner, inner_path in nested:
        section(inner, inner_path, seen, out)


def tag_name(model: type[BaseModel]) -> str:
    return "name" if "name" in model.model_fields else "type"


def render() -> str:
    """The whole page."""
    from emasim.scenarios.axis_scenario import AxisScenario
    from emasim.scenarios.schema import Scenario

    out = [INTRO]
    seen: set = set()
    section(Scenario, "scenario", seen, out)
    out += [
        '# Axis scenarios (`kind = "axis"`, `emasim identify`)',
        "",
    ]
    section(AxisScenario, "axis scenario", seen, out)
    return "\n".join(out).rstrip() + "\n"


if __name__ == "__main__":
    PAGE.write_text(render())
    print(f"wrote {PAGE}")
