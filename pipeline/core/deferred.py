"""Work named now and imported later: a stage names the function and the job of its items by
``"module:attribute"``, so that when every item is up to date it never imports what the work
needs (scipy, pandas, OpenCV, the models: 0.1-0.6 s each at a stage's start)."""

from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping


@dataclass(frozen=True)
class Deferred:
    """``factory(*args, **kwargs)``, made only when needed; the factory is named ``"module:attribute"``
    (e.g. ``"pipeline.pose.tracking:TrackJob"``) and Deferred arguments are made first."""
    factory: str
    args: tuple = ()
    kwargs: Mapping[str, Any] = field(default_factory=dict)


def resolve(name: str | Callable) -> Callable:
    """``"module:attribute.attribute"`` imported and looked up; a callable is returned as it is."""
    if callable(name):
        return name
    module, _, attribute = name.partition(":")
    found: Any = importlib.import_module(module)
    for part in attribute.split("."):
        found = getattr(found, part)
    return found


def make_payload(payload: Any) -> Any:
    """``payload`` itself, or what a ``Deferred`` makes."""
    if not isinstance(payload, Deferred):
        return payload
    return resolve(payload.factory)(*map(make_payload, payload.args),
                                    **{k: make_payload(v) for k, v in payload.kwargs.items()})


def options_from_params(cls: str | type, params: Mapping[str, Any]) -> Any:
    """The options dataclass ``cls`` with each of its fields that ``params`` names taken from there."""
    cls = resolve(cls)
    return cls(**{f.name: params[f.name] for f in dataclasses.fields(cls) if f.name in params})
