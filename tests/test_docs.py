"""docs/blocks/ holds one generated reference page per block kind, kept up to date."""

from pathlib import Path

import pytest

import loopworks
from loopworks.blocks import reference

DOCS = Path(__file__).resolve().parent.parent / "docs" / "blocks"


@pytest.mark.parametrize("kind", loopworks.kinds())
def test_reference_page_is_current(kind: str) -> None:
    page = DOCS / f"{kind}.md"
    assert page.exists(), f"run: loopworks blocks {kind} --markdown > docs/blocks/{kind}.md"
    assert page.read_text() == reference.markdown(loopworks.block_class(kind)), \
        f"stale page: run loopworks blocks {kind} --markdown > docs/blocks/{kind}.md"


@pytest.mark.parametrize("kind", loopworks.kinds())
def test_every_parameter_has_unit_or_choices_and_meaning(kind: str) -> None:
    cls = loopworks.block_class(kind)
    for p in cls.PARAMS:
        assert p.meaning, f"{kind}.{p.name} has no meaning"
        assert p.range_text()
    for port in (*cls.INPUTS, *cls.OUTPUTS):
        assert port.meaning, f"{kind}.{port.name} has no meaning"
