"""The block kinds of loopworks: ``create_block(kind, **params)``, ``kinds()``,
``block_class(kind)``.

The modules in ``BLOCK_MODULES`` define the kinds (each registers its classes with
:func:`loopworks.blocks.registry.register`); they are imported on first use, so
``import loopworks`` stays light. This module sits above ``blocks/``, ``vendors/`` and
``plant/`` (it names their modules) and below ``tuning/``, ``sim/`` and the CLI, which look
kinds up here. A new kind is one module that registers it, listed here.

Why a module and not ``[project.entry-points."loopworks.kinds"]``: entry points live in the
installed package's metadata, so a kind added to the source is missing until the package is
installed again (a stale editable install lists the old kinds, silently); and loopworks has
no third-party kinds to discover yet. A plugin can still register its own classes with
``register`` when it is imported.
"""

from __future__ import annotations

import importlib
from typing import Any

from loopworks.blocks.block import Block
from loopworks.blocks.controller import Controller
from loopworks.blocks.registry import registered
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

_loaded = False


def _load() -> None:
    global _loaded
    if not _loaded:
        for name in BLOCK_MODULES:
            importlib.import_module(name)
        _loaded = True


def kinds() -> list[str]:
    """Every registered block kind, sorted."""
    _load()
    return sorted(registered())


def controller_kinds() -> list[str]:
    """The kinds whose class is a :class:`~loopworks.blocks.controller.Controller`, sorted."""
    return [k for k in kinds() if issubclass(registered()[k], Controller)]


def block_class(kind: str) -> type[Block]:
    """The class registered for ``kind`` (any letter case)."""
    _load()
    found = registered()
    cls = found.get(kind) or found.get(kind.lower())
    if cls is None:
        raise UnknownKindError(f"unknown block kind '{kind}'; known kinds: {', '.join(kinds())}")
    return cls


def create_block(kind: str, **params: Any) -> Block:
    """Make a block of ``kind`` with validated ``params`` (names in any letter case).

    The kinds are listed in the docstring of :func:`loopworks.create_block` (kept equal to
    :func:`kinds` by a test) and by ``loopworks blocks``."""
    return block_class(kind)(**params)
