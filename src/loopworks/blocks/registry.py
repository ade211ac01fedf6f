"""The registration of block kinds: ``@register`` and a lookup of what is registered.

Block modules register their classes with ``@register`` when they are imported. Which modules
make up loopworks' kinds, and ``create_block(kind, **params)``, ``kinds()`` and
``block_class()`` over all of them, are in :mod:`loopworks.catalog`, above the layers that define
the kinds: this module, the bottom layer's, names nothing above it.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import TypeVar

from loopworks.blocks.block import Block

_REGISTRY: dict[str, type[Block]] = {}

B = TypeVar("B", bound=type[Block])


def register(cls: B) -> B:
    """Class decorator: make ``cls`` available under ``cls.kind``."""
    if not cls.kind:
        raise TypeError(f"{cls.__name__} has no kind")
    _REGISTRY[cls.kind] = cls
    return cls


def registered() -> Mapping[str, type[Block]]:
    """The classes registered so far (their modules imported), by kind; a read-only view."""
    return MappingProxyType(_REGISTRY)
