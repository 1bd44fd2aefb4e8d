"""``acv render``: one image per candidate; bad input is one line and exit code 2."""

from __future__ import annotations

from pathlib import Path

import pytest
from PIL import Image

import app.cli.render as render_cli
from engine.pipeline import run_tournament
from engine.render import BackendError
from engine.render.backend import missing_backend_message
from engine.treefile import dump_tree
from tests.support.cli import acv, acv_process

N_CANDIDATES = 4


@pytest.fixture(scope="module")
def tree(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("render") / "human.json"
    dump_tree(
        run_tournament(
            env_id="Hopper-v5", n_candidates=N_CANDIDATES, p=0.9, seed=0, teacher="standing"
        ),
        path,
    )
    return path


@pytest.mark.process
def test_writes_one_image_per_candidate(tree: Path, tmp_path: Path) -> None:
    out = tmp_path / "renders"
    done = acv_process(
        "render",
        "--tree",
        tree,
        "--out",
        out,
        "--view",
        "three-quarter",
        "--size",
        "72",
        "--format",
        "png",
    )
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in out.iterdir()) == [f"{i}.png" for i in range(N_CANDIDATES)]
    for path in out.iterdir():
        with Image.open(path) as image:
            assert (image.format, image.size) == ("PNG", (72, 72))
    assert f"wrote {N_CANDIDATES} png images" in done.stdout
    assert f"{N_CANDIDATES}/{N_CANDIDATES}" in done.stderr  # the progress bar finished


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--view", "top"], "unknown view"),
        (["--size", "15"], "16..1920"),
        (["--size", "5000"], "16..1920"),
        (["--format", "gif"], "jpg or png"),
        (["--tree", "missing.json"], "cannot read tree file"),
        (["--out", "{tree}"], "cannot write images"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    tree: Path, tmp_path: Path, args: list[str], words: str
) -> None:
    args = [a.format(tree=tree) for a in args]
    if "--tree" not in args:
        args = ["--tree", str(tree), *args]
    if "--out" not in args:
        args = [*args, "--out", str(tmp_path / "out")]
    result = acv("render", *args)
    assert result.exit_code == 2
    assert words in result.stderr and result.stderr.count("\n") == 1


def test_missing_backend_is_one_clear_line(
    tree: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def unavailable() -> str:
        raise BackendError(missing_backend_message())

    monkeypatch.setattr(render_cli, "activate", unavailable)
    result = acv("render", "--tree", tree, "--out", tmp_path)
    assert result.exit_code == 2
    assert "libegl1 libegl-mesa0 libgl1-mesa-dri" in result.stderr
    assert "libosmesa6" in result.stderr
    assert not list(tmp_path.iterdir())
