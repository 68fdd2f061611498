"""The plant's elements, one module each: to add an element, add its module here.

Every module of this package that holds an :class:`~emasim.plant.element.Element` at module
level contributes it to the plant: :func:`discover` imports them all and collects those
elements, and emasim.plant.actuator orders them by their ``after`` declarations.
"""

import importlib
import pkgutil

from ..element import Element


def discover() -> tuple[Element, ...]:
    """Every element declared at module level in this package's modules."""
    found: dict[str, Element] = {}
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda info: info.name):
        module = importlib.import_module(f"{__name__}.{info.name}")
        for value in vars(module).values():
            if isinstance(value, Element):
                if value.name in found and found[value.name] is not value:
                    raise ValueError(f"two elements are named '{value.name}'")
                found[value.name] = value
    return tuple(found.values())
