"""The block kinds of loopworks: ``create_block(kind, **params)``, ``kinds()``,
``block_class(kind)``.

The kinds are registered by the modules that define them (with
:func:`loopworks.blocks.registry.register`): every module of the packages in
``KIND_PACKAGES`` (the vendors' blocks and the plant's, found by walking the packages) and the
generic kinds of the bottom layer in ``BLOCK_MODULES``. They are imported on first use, so
``import loopworks`` stays light. This module sits above ``blocks/``, ``vendors/`` and
``plant/`` and below ``tuning/``, ``sim/`` and the CLI, which look kinds up here. A new vendor
block is one module in ``loopworks/vendors/`` that registers its class: nothing here changes.

Why not ``[project.entry-points."loopworks.kinds"]``: entry points live in the installed
package's metadata, so a kind added to the source is missing until the package is installed
again (a stale editable install lists the old kinds, silently); and loopworks has no
third-party kinds to discover yet. A plugin can still register its own classes with
``register`` when it is imported.
"""

from __future__ import annotations

import importlib
import pkgutil
from typing import Any

from loopworks.blocks.block import Block
from loopworks.blocks.controller import Controller
from loopworks.blocks.registry import registered
from loopworks.errors import UnknownKindError

#: packages whose every module may define kinds
KIND_PACKAGES: tuple[str, ...] = ("loopworks.vendors", "loopworks.plant")
#: the generic kinds of the bottom layer (blocks/ also holds the block model itself)
BLOCK_MODULES: tuple[str, ...] = ("loopworks.blocks.pid", "loopworks.blocks.compensators",
                                  "loopworks.blocks.relay")

_loaded = False


def _load() -> None:
    global _loaded
    if not _loaded:
        for name in BLOCK_MODULES:
            importlib.import_module(name)
        for package in KIND_PACKAGES:
            path = importlib.import_module(package).__path__
            for module in pkgutil.walk_packages(path, package + "."):
                importlib.import_module(module.name)
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
