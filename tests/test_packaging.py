"""What a package others can install says about itself (issue 44 §4): one version, shown by
``acv --version``, read by ``pyproject.toml`` and named by the changelog and the dataset
card; the MIT licence and the citation; and, in a checkout, the resource folders beside the
``app`` package (``tests/test_wheel.py`` builds and serves the wheel)."""

from __future__ import annotations

import os
import tomllib

import pytest
import yaml

from app.core import resources
from app.labelling.dataset_card import Facts, readme
from engine import __version__
from engine.provenance import LIBRARIES, provenance
from tests.support.cli import acv
from tests.support.server import REPO


def test_acv_version_prints_the_one_version() -> None:
    result = acv("--version")
    assert result.exit_code == 0 and result.output == f"acv {__version__}\n"


def test_pyproject_reads_the_version_from_the_engine() -> None:
    project = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert "version" not in project["project"] and project["project"]["dynamic"] == ["version"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "engine.__version__"}
    assert __version__ != "0.1.0"


def test_the_changelog_has_an_entry_for_this_version() -> None:
    assert f"\n## [{__version__}] - " in (REPO / "CHANGELOG.md").read_text()


def test_the_licence_is_mit_and_the_citation_names_the_paper() -> None:
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert project["license"] == "MIT" and project["license-files"] == ["LICENSE"]
    assert (REPO / "LICENSE").read_text().startswith("MIT License\n")
    cff = yaml.safe_load((REPO / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["license"] == "MIT"
    assert cff["title"].startswith("ACV")
    paper = cff["preferred-citation"]
    assert paper["title"].startswith("Advice Conformance Verification by Reinforcement")
    assert [a["family-names"] for a in paper["authors"]] == ["Verma", "Kharkwal", "Kambhampati"]


def test_provenance_names_the_version_and_the_libraries() -> None:
    found = provenance()
    assert found["acv"] == __version__ and set(found["libraries"]) == set(LIBRARIES)
    assert all(found["libraries"].values())  # all installed here
    assert found["commit"] is None or len(found["commit"].removesuffix("+dirty")) == 40


def test_the_dataset_card_names_the_version_that_exported_it() -> None:
    facts = Facts("s", "Hopper-v5", 4, 0.9, 0, "uniform", "", 1, 3, 1, "mit")
    assert f"exported by ACV {__version__}." in readme(facts)


def test_the_checkout_finds_its_folders_beside_the_package() -> None:
    """An editable install (``make``) reads the repository's own folders."""
    found = {name: resources.resource_dir(name) for name in resources.FOLDERS}
    assert found == {name: REPO / name for name in resources.FOLDERS}
    assert resources.child_pythonpath().split(os.pathsep)[0] == str(REPO)


def test_an_install_reads_the_folders_inside_the_package(tmp_path, monkeypatch) -> None:
    """A wheel's folders are inside ``app``; beside it only in ACV's own checkout, so a
    ``templates`` folder of another project in ``site-packages`` is never taken."""
    package = tmp_path / "site-packages" / "app"
    (package / "templates").mkdir(parents=True)
    (tmp_path / "site-packages" / "static").mkdir()
    monkeypatch.setattr(resources, "package_dir", lambda: package)
    assert resources.resource_dir("templates") == package / "templates"
    with pytest.raises(FileNotFoundError, match="static folder is missing"):
        resources.resource_dir("static")
