"""docs/blocks/ holds one generated reference page per block kind, kept up to date."""

from pathlib import Path

import pytest

import loopworks
from loopworks.blocks import reference, sources

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


def test_every_kind_has_a_specification() -> None:
    """A bare "spec X.Y" on each kind's page means one document, named in the sources table."""
    documents = {k: sources.kind_document(loopworks.block_class(k).__module__)
                 for k in loopworks.kinds()}
    assert set(documents.values()) == set(sources.DOCUMENTS)
    vendor = {k for k, d in documents.items() if d == sources.VENDOR}
    assert vendor == {"deltav.calc", "deltav.pid", "deltav.sggn", "deltav.stick_slip",
                      "e2.pid", "ge.pid_ind", "ge.pid_isa", "s5.pid"}


def _page_parts(kind: str) -> tuple[str, str]:
    text = (DOCS / f"{kind}.md").read_text()
    assert text.count(reference.SECTION_HEADING + "\n") == 1, f"{kind}: one Sources section"
    body, listed = text.split(reference.SECTION_HEADING + "\n")
    assert "\n## " not in listed, f"{kind}: the Sources section must be the last one"
    return body, listed


@pytest.mark.parametrize("kind", loopworks.kinds())
def test_every_citation_is_explained_in_sources(kind: str) -> None:
    """Every "spec X.Y", R number, seed and tag on a page is in loopworks.blocks.sources (a
    section, reference or tag that is not fails here: add it there), and the page's Sources
    section lists each one."""
    body, listed = _page_parts(kind)
    document = sources.kind_document(loopworks.block_class(kind).__module__)
    found = reference.citations(body, document)
    assert reference.unresolved(found, document) == [], \
        f"{kind}: cited but not in loopworks/blocks/sources.py"
    for doc, number in found.sections:
        assert f"* spec {number} ({doc}): {sources.SECTIONS[doc][number]}\n" in listed
    for ref in found.references:
        assert f"* {ref}: {sources.REFERENCES[ref]}\n" in listed
    for seed in found.seeds:
        assert f"* seed {seed}: {sources.SEEDS[seed]}\n" in listed
    meanings = {**sources.TAGS[document], **sources.PROJECT_TAGS}
    for tag in found.tags:
        assert f"* [{tag}] (" in listed and meanings[tag] in listed
    assert f"* {document}: {sources.DOCUMENTS[document]}\n" in listed


def test_citation_parser() -> None:
    """The forms the pages use, and what is not a citation."""
    def sections(text: str, document: str = sources.VENDOR) -> set[tuple[str, str]]:
        return reference.citations(text, document).sections

    v, p = sources.VENDOR, sources.PLANT
    assert sections("(spec 1.2/1.7 step 10)") == {(v, "1.2"), (v, "1.7")}
    assert sections("Equations (spec 2.4-2.7, seed 002)") == {(v, f"2.{i}") for i in range(4, 8)}
    assert sections("(spec 1.2 implementation note, 1.3, 1.9; x 2.5)", p) == {
        (p, "1.2"), (p, "1.3"), (p, "1.9")}
    assert sections("Spec 4.2 vs 4.7 step 7 [A]: the\n  literal") == {(v, "4.2"), (v, "4.7")}
    assert sections("[A, spec\n  1.7 step 13]") == {(v, "1.7")}
    assert sections("Spec 4.3 [?], 4.1 BAL_TIME [?].") == {(v, "4.3"), (v, "4.1")}
    assert sections("(spec 6.3 lines 26, 28)") == {(v, "6.3")}
    assert sections("(spec 1.8, S = 3, J = 1, valve at rest)") == {(v, "1.8")}
    assert sections("(spec 1.6: 3.57 s)") == {(v, "1.6")}
    assert sections("(spec vendor-blocks 6.5, 8 item 5)", p) == {(v, "6.5"), (v, "8")}
    assert sections("plant-and-tuning section 6 item 3 and spec 2.3") == {(p, "6"), (v, "2.3")}
    assert sections("the spec's 2.13 example; the spec's [I] points") == {(v, "2.13")}
    assert sections("GFK-2950C section 7.7; specific 1.2; issue 11 point 8") == set()
    found = reference.citations("R40-R42, [R49, R50], R2010; seed 000_x, seed 001", v)
    assert found.references == {"R40", "R41", "R42", "R49", "R50"}
    assert found.seeds == {"001"}
    tags = reference.citations("[A] [?, spec 1.5] [V as printed] [0, 100] [I, loopworks "
                               "design] [x_ss - S, x_ss + J] [A: why]", v).tags
    assert tags == {"A", "?", "V", "I", "loopworks design"}


def test_unknown_citations_are_reported() -> None:
    """A citation the sources table does not explain is named, so a new one cannot go
    unexplained (and the page says so instead of inventing a title)."""
    found = reference.citations("(spec 4.99; R99; seed 999) [L] [A]", sources.VENDOR)
    assert reference.unresolved(found, sources.VENDOR) == [
        "spec 4.99 (vendor-blocks)", "R99", "seed 999", "[L]"]
    assert "(not in loopworks.blocks.sources)" in reference.sources_section(found,
                                                                            sources.VENDOR)


ROOT = DOCS.parent.parent
SCRIPTS = sorted([*(ROOT / "docs" / "scripts").glob("*.py"),
                  *(ROOT / "benchmarks").glob("*.py")])


@pytest.mark.parametrize("path", SCRIPTS, ids=[p.name for p in SCRIPTS])
def test_every_loopworks_name_a_script_imports_exists(path: Path) -> None:
    """docs/scripts/conversion_plot.py imported create_block from a module that no longer
    has it and failed at once, while docs/conversion.md said it runs in about 3 s (found by a
    user following the docs). Every `from loopworks... import NAME` of the scripts the docs
    and benchmarks/README.md name must resolve (the scripts themselves take minutes)."""
    import ast
    import importlib

    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("loopworks"):
            module = importlib.import_module(str(node.module))
            for alias in node.names:
                if not hasattr(module, alias.name):  # a submodule: importable by its name
                    importlib.import_module(f"{node.module}.{alias.name}")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("loopworks"):
                    importlib.import_module(alias.name)
