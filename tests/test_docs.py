"""The documentation's examples run, its links resolve, and what the code cites of it exists.

* every ```python block of docs/*.md runs, the blocks of one page in order in one namespace, in a
  temporary working directory that has the repository's models/ (a block whose first line is
  ``# not run`` is skipped);
* every ```xml block of docs/*.md loads with the engine (mjrft.load_model), builds a
  GranularField and steps;
* every relative link of README.md, docs/*.md, benchmarks/RESULTS.md and envs/README.md points to
  an existing file, and its #anchor to a heading there;
* every citation of a docs page in the code (``docs/stability.md, "RK4"``,
  ``docs/design.md 2.2``, ``docs/design.md section 3``) names a page, heading or item that exists;
* every test the pages cite (``tests/test_x.py::test_y``) exists;
* docs/cli.md documents exactly the options of the ``mjrft`` command.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

import mjrft
from mjrft import GranularField

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md"))
PAGES = [ROOT / "README.md", *DOCS, ROOT / "benchmarks" / "RESULTS.md", ROOT / "envs" / "README.md"]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", flags=re.M | re.S)


def blocks(path: Path, lang: str) -> list[str]:
    return [code for kind, code in FENCE.findall(path.read_text()) if kind == lang]


def slug(heading: str) -> str:
    """GitHub's anchor for a heading."""
    text = re.sub(r"[`*_]{2,}|`", "", heading.strip().lower())
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def headings(path: Path) -> list[str]:
    text = FENCE.sub("", path.read_text())
    return [m.group(1).strip() for m in re.finditer(r"^#{1,6} (.+)$", text, flags=re.M)]


def test_there_are_docs():
    assert len(DOCS) >= 10


@pytest.mark.parametrize("doc", [d for d in DOCS if blocks(d, "python")], ids=lambda d: d.name)
def test_python_blocks_run(doc, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "models").symlink_to(ROOT / "models", target_is_directory=True)
    namespace = {"__name__": f"docs_{doc.stem}"}
    for i, code in enumerate(blocks(doc, "python")):
        if code.startswith("# not run"):
            continue
        exec(compile(code, f"{doc.relative_to(ROOT)} (python block {i + 1})", "exec"), namespace)


@pytest.mark.parametrize("doc", [d for d in DOCS if blocks(d, "xml")], ids=lambda d: d.name)
def test_xml_blocks_compile_and_step(doc):
    for xml in blocks(doc, "xml"):
        model = mjrft.load_model(xml)
        field = GranularField(model)
        data = mujoco.MjData(model)
        for _ in range(50):
            mujoco.mj_step(model, data)
        assert np.all(np.isfinite(data.qpos))
        assert field.stats_of(data)["calls"] == 50


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(page):
    text = FENCE.sub("", page.read_text())
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+:", target):
            continue
        file, _, anchor = target.partition("#")
        dest = (page.parent / file).resolve() if file else page
        assert dest.exists(), f"{page.name}: link to missing {target}"
        if anchor and dest.suffix == ".md":
            anchors = [slug(h) for h in headings(dest)]
            assert anchor in anchors, f"{page.name}: no heading #{anchor} in {dest.name}"


CITATION = re.compile(
    r"docs/(\w+)\.md(?:,? \"([^\"]+)\"| (?:section |sections? )?(\d+(?:\.\d+)?))?"
)


def _cited():
    for base in ("mjrft", "envs", "models", "tests", "benchmarks", "scripts", "docs"):
        for path in sorted((ROOT / base).rglob("*")):
            if path.suffix not in (".py", ".xml", ".md") or path.name == "test_docs.py":
                continue
            for m in CITATION.finditer(path.read_text(errors="replace")):
                yield path.relative_to(ROOT), m.group(1), m.group(2), m.group(3)
    for m in CITATION.finditer((ROOT / "pyproject.toml").read_text()):
        yield "pyproject.toml", m.group(1), m.group(2), m.group(3)


def test_code_citations_of_the_docs_exist():
    cited = list(_cited())
    assert cited  # the code does cite the docs
    for where, page, heading, number in cited:
        doc = ROOT / "docs" / f"{page}.md"
        assert doc.exists(), f"{where} cites missing docs/{page}.md"
        if heading:
            hs = [h.lower() for h in headings(doc)]
            assert any(heading.lower() in h for h in hs), f'{where}: no "{heading}" in {doc.name}'
        if number:
            text = doc.read_text()
            pattern = (
                rf"^## {re.escape(number)}\. "
                if "." not in number
                else rf"\*\*{re.escape(number)} "
            )
            assert re.search(pattern, text, flags=re.M), f"{where}: no {number} in {doc.name}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_cited_tests_exist(page):
    for file, name in re.findall(r"(tests/\w+\.py)::(\w+)", page.read_text()):
        path = ROOT / file
        assert path.exists(), f"{page.name} cites missing {file}"
        assert re.search(rf"^def {name}\(", path.read_text(), flags=re.M), f"no {file}::{name}"


def _options(parser: argparse.ArgumentParser) -> set[str]:
    opts = set()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                opts |= _options(sub)
        opts |= {o for o in action.option_strings if o.startswith("--")}
    return opts


def test_cli_page_documents_every_option():
    from mjrft.app.cli import build_parser

    documented = set(
        re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", (ROOT / "docs" / "cli.md").read_text())
    )
    assert documented == _options(build_parser())
