"""The registry of block kinds: ``create_block(kind, **params)`` and ``kinds()``.

Block modules register their classes with ``@register``. The modules listed in
``BLOCK_MODULES`` are imported on first use, so ``import loopworks`` stays light.
"""

from __future__ import annotations

import importlib
from typing import Any, TypeVar

from loopworks.blocks.block import Block
from loopworks.errors import UnknownKindError

BLOCK_MODULES: tuple[str, ...] = (
    "loopworks.blocks.pid",
    "loopworks.plant.process",
    "loopworks.vendors.ge_pacsystems",
    "loopworks.vendors.siemens_s5",
    "loopworks.vendors.emerson_e2",
    "loopworks.vendors.deltav.pid",
    "loopworks.vendors.deltav.stick_slip",
    "loopworks.vendors.deltav.sggn",
    "loopworks.vendors.deltav.calc",
    "loopworks.plant.valve",
    "loopworks.plant.karnopp",
    "loopworks.plant.sensor",
    "loopworks.plant.disturbance",
    "loopworks.blocks.compensators",
    "loopworks.blocks.relay",
)

_REGISTRY: dict[str, type[Block]] = {}
_loaded = False

B = TypeVar("B", bound=type[Block])


def register(cls: B) -> B:
    """Class decorator: make ``cls`` available under ``cls.kind``."""
    if not cls.kind:
        raise TypeError(f"{cls.__name__} has no kind")
    _REGISTRY[cls.kind] = cls
    return cls


def _load() -> None:
    global _loaded
    if not _loaded:
        for name in BLOCK_MODULES:
            importlib.import_module(name)
        _loaded = True


def kinds() -> list[str]:
    """Every registered block kind, sorted."""
    _load()
    return sorted(_REGISTRY)


def block_class(kind: str) -> type[Block]:
    """The class registered for ``kind`` (any letter case)."""
    _load()
    cls = _REGISTRY.get(kind) or _REGISTRY.get(kind.lower())
    if cls is None:
        raise UnknownKindError(f"unknown block kind '{kind}'; known kinds: {', '.join(kinds())}")
    return cls


def create_block(kind: str, **params: Any) -> Block:
    """Make a block of ``kind`` with validated ``params`` (names in any letter case).

    The kinds are listed in the docstring of :func:`loopworks.create_block` (kept equal to
    :func:`kinds` by a test) and by ``loopworks blocks``."""
    return block_class(kind)(**params)
