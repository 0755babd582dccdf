"""Controllers by name: the built-in set, the `frictiongym.controllers` entry-point group (a package
registers `name = "module:factory"`, the factory taking no arguments and returning a Controller), and
saved models (model directories with a manifest, added by the caller)."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from importlib.metadata import entry_points

from .base import Controller, Zero
from .classical import PD, PID, RDFC, CoulombViscousFF, LuGreObserver, Southward, StateFeedback

ENTRY_POINT_GROUP = "frictiongym.controllers"

BUILTIN: dict[str, Callable[[], Controller]] = {
    "Zero": Zero,
    "PD": PD,
    "PID": PID,
    "Southward": Southward,
    "RDFC": RDFC,
    "SF": StateFeedback,
    "SF+relay": partial(StateFeedback, "relay"),
    "SF+highgain": partial(StateFeedback, "highgain"),
    "LuGreObserver": LuGreObserver,
    "CoulombViscousFF": CoulombViscousFF,
}


def available() -> dict[str, Callable[[], Controller]]:
    """Every controller factory by name: built-ins, then the entry-point group's (which may not shadow
    a built-in name)."""
    out = dict(BUILTIN)
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name in out:
            raise ValueError(f"entry point {ep.name!r} ({ep.value}) shadows a built-in controller")
        out[ep.name] = ep.load()
    return out


def make(name: str) -> Controller:
    """A new controller called name (unknown names are an error listing the available ones)."""
    factories = available()
    if name not in factories:
        raise ValueError(f"unknown controllers [{name!r}]; available: {list(factories)}")
    return factories[name]()
