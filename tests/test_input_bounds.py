"""Every number a scenario can set has a lower and an upper bound, and types are strict.

The walk starts at Scenario and visits every model reachable from it (plant, sensors,
controllers of every loop, signal terms, solver), tuple and list elements included. A field
added without bounds fails here, naming it.
"""

import typing

import annotated_types as at
import pytest
from pydantic import BaseModel
from pydantic.fields import FieldInfo

from emasim.errors import InputError
from emasim.scenarios.loader import load_scenario
from emasim.scenarios.schema import Scenario

LOWER, UPPER = (at.Ge, at.Gt), (at.Le, at.Lt)
NOT_PHYSICS = {("Scenario", "tuning")}  # a free-form record of how gains were tuned


def numbers_in(annotation, metadata=()):
    """(has lower bound, has upper bound) of every float or int inside an annotation."""
    if typing.get_origin(annotation) is typing.Annotated:
        base, *more = typing.get_args(annotation)
        yield from numbers_in(base, (*metadata, *more))
        return
    metadata = tuple(
        part for m in metadata for part in (m.metadata if isinstance(m, FieldInfo) else [m])
    )
    if annotation in (float, int):
        yield (
            any(isinstance(m, LOWER) for m in metadata),
            any(isinstance(m, UPPER) for m in metadata),
        )
        return
    origin = typing.get_origin(annotation)
    container = origin in (tuple, list, dict)
    for arg in typing.get_args(annotation):
        if (
            arg is type(None)
            or arg is Ellipsis
            or isinstance(arg, type)
            and issubclass(arg, BaseModel)
        ):
            continue
        # a union member (X | None) shares the field's bounds; a container's elements do not
        yield from numbers_in(arg, () if container else metadata)


def models_in(annotation):
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        yield annotation
        return
    for arg in typing.get_args(annotation):
        yield from models_in(arg)


def unbounded_fields() -> list[str]:
    seen, todo, missing = set(), [Scenario], []
    while todo:
        model = todo.pop()
        if model in seen:
            continue
        seen.add(model)
        for name, field in model.model_fields.items():
            if (model.__name__, name) in NOT_PHYSICS:
                continue
            for lower, upper in numbers_in(field.annotation, tuple(field.metadata)):
                if not (lower and upper):
                    missing.append(f"{model.__name__}.{name}")
            todo.extend(models_in(field.annotation))
    return sorted(set(missing)), seen


def test_every_number_has_both_bounds():
    missing, seen = unbounded_fields()
    assert len(seen) > 20  # the walk reached the plant, controllers and signals
    assert missing == []


@pytest.mark.parametrize(
    "setting, field",
    [
        ('duration_s="0.05"', "duration_s"),
        ("duration_s=true", "duration_s"),
        ("plant.motor.pole_pairs=4.0", "plant.motor.pole_pairs"),
        ("plant.motor.pole_pairs=true", "plant.motor.pole_pairs"),
        ('controllers.speed.bandwidth_Hz="50"', "controllers.speed.bandwidth_Hz"),
    ],
)
def test_no_string_or_bool_becomes_a_number(setting, field):
    with pytest.raises(InputError, match=field.replace(".", r"\.")):
        load_scenario("speed-step", settings=[setting])


def test_tuple_elements_are_bounded_and_strict():
    base = "plant.linkage.hinge_clearance_mm"
    for value, words in (
        ("[0.01, 0.01, -0.01, 0.01]", "greater than or equal to 0"),
        ("[0.01, 0.01, true, 0.01]", "valid number"),
        ("[0.01, 0.01, 0.01]", r"hinge_clearance_mm\.3: Field required"),
    ):
        with pytest.raises(InputError, match=words):
            load_scenario("bench-step", settings=[f"{base}={value}"])
