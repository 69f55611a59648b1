"""
The documentation stays true to the code: generated references, links and cited sections.

docs/reference/settings.md and cli.md are written from the code (``config.field`` metadata,
the argparse parser) by tools/gen_reference.py; a changed default, range, meaning or flag
makes them out of date.  Every relative link in the docs and the README must reach a file,
and an anchor a heading of it; every ``docs/NAME.md`` that the package, the tests, the
benches or the README name must exist, with the section they quote.
"""

import importlib.util
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
HEADING = re.compile(r"^#{1,6}\s+(.*?)\s*#*\s*$")
# ``docs/NAME.md, "Section"`` or ``docs/NAME.md, Section)`` as code and tests cite a section
CITED = re.compile(r'docs/([\w/]+\.md)(?:,\s*(?:"([^"]+)"|([A-Z][\w-]*)\)))?')


def _generator():
    spec = importlib.util.spec_from_file_location("gen_reference",
                                                  ROOT / "tools" / "gen_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _slug(heading):
    """Return GitHub's anchor of a heading: lower case, punctuation dropped, spaces to -."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def _headings(path):
    out, fenced = [], False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            fenced = not fenced
            continue
        m = None if fenced else HEADING.match(line)
        if m:
            out.append(m.group(1))
    return out


def _markdown_files():
    return sorted(DOCS.rglob("*.md")) + [ROOT / "README.md"]


def test_settings_and_cli_references_are_what_the_code_declares():
    gen = _generator()
    for path, text in ((gen.OUT, gen.render()), (gen.CLI_OUT, gen.render_cli())):
        assert path.read_text() == text, (
            f"{path.relative_to(ROOT)} is out of date: run .venv/bin/python "
            "tools/gen_reference.py")


def test_every_relative_link_reaches_a_file_and_its_heading():
    broken, checked = [], 0
    for md in _markdown_files():
        for target in LINK.findall(md.read_text()):
            checked += 1
            if re.match(r"^[a-z]+:", target):
                continue            # http:, https:, mailto:
            path, _, anchor = target.partition("#")
            dest = (md.parent / path).resolve() if path else md
            if not dest.exists():
                broken.append(f"{md.relative_to(ROOT)}: {target} (no such file)")
            elif anchor and dest.suffix == ".md" and \
                    anchor not in {_slug(h) for h in _headings(dest)}:
                broken.append(f"{md.relative_to(ROOT)}: {target} (no such heading)")
    assert checked > 50, "no links found: the pattern no longer matches the docs"
    assert not broken, "\n".join(broken)


def test_docs_named_in_code_tests_and_benches_exist_with_their_sections():
    missing = []
    sources = [p for d in ("bb_friction_ros", "test", "bench", "tools")
               for p in (ROOT / d).rglob("*.py")] + [ROOT / "README.md"]
    for src in sources:
        if src == pathlib.Path(__file__).resolve():
            continue
        for name, quoted, bare in CITED.findall(src.read_text()):
            doc = DOCS / name
            if not doc.exists():
                missing.append(f"{src.relative_to(ROOT)}: docs/{name}")
                continue
            section = quoted or bare
            if section and not any(section.lower() in h.lower() for h in _headings(doc)):
                missing.append(f"{src.relative_to(ROOT)}: docs/{name}, section {section!r}")
    assert not missing, "\n".join(missing)


def test_the_docs_index_lists_every_page():
    index = (DOCS / "README.md").read_text()
    pages = [p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md") if p.name != "README.md"]
    unlisted = [p for p in pages if f"]({p})" not in index]
    assert not unlisted, f"docs/README.md does not list: {unlisted}"
