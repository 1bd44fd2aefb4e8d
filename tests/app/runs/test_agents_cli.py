"""``acv agents``: an external experiment and imports from the command line (issue 44 §2), the
same services as the API. An SB3 ``MlpPolicy`` zip is converted to ONNX (only the ONNX is
stored); bad input is one line on stderr, exit code 2, and nothing stored.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import torch
from click.testing import Result
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from app.cli import agents as agents_cli
from app.models import Run
from app.runs.declared import ALGORITHM_KEY, SEED_KEY, TIMESTEPS_KEY
from app.runs.imported import tree_digest
from engine.policies import export
from engine.policies.onnx_check import OnnxLimits
from engine.policies.sb3 import Sb3Limits
from engine.treefile import load_tree
from tests.support.agents import (
    create_external,
    external_data,
    forbidden_op,
    obs_norm,
    policy,
    sb3_zip,
    stored_files,
    wrong_sizes,
)
from tests.support.cli import acv
from tests.support.runs import run_app
from tests.support.studies import new_study
from tests.support.web import ADMIN

# postgres_only: training is the subject, not storage.
pytestmark = pytest.mark.postgres_only


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    return new_study(client, seed=7)


@pytest.fixture
def run(settings, monkeypatch: pytest.MonkeyPatch) -> Callable[..., Result]:
    """``acv`` in this process, on this module's database and data dir."""
    monkeypatch.setenv("ACV_DATA_DIR", str(settings.data_dir))
    monkeypatch.setenv("DATABASE_URL", settings.sqlalchemy_url)
    return acv


def _state(client: TestClient) -> tuple[int, list[str]]:
    """Runs in the database and policies stored."""
    with client.app.state.runtime.sessions() as session:
        runs = session.scalar(select(func.count()).select_from(Run))
    state = client.app.state
    return runs, stored_files(state.job_settings.runs_root(state.runtime.settings))


def _write(folder: Path, name: str, data: bytes) -> Path:
    path = folder / name
    path.write_bytes(data)
    return path


def test_the_cli_s_limits_and_keys_are_the_engine_s() -> None:
    """Constants the CLI and services keep apart from the modules that would load torch."""
    assert Sb3Limits().max_zip_bytes == agents_cli.MAX_ZIP_BYTES
    keys = (export.ALGORITHM_KEY, export.TIMESTEPS_KEY, export.SEED_KEY)
    assert keys == (ALGORITHM_KEY, TIMESTEPS_KEY, SEED_KEY)


def test_an_external_experiment_and_its_imports_from_the_cli(
    client: TestClient, study: dict[str, Any], run, tmp_path: Path
) -> None:
    tree_file = tmp_path / "advice.json"
    created = run(
        "agents", "experiment", "--study", study["id"], "--teacher", "good", "--seeds", "2",
        "--tree-out", tree_file,
    )  # fmt: skip
    assert created.exit_code == 0, created.output
    experiment = int(re.search(r"external experiment (\d+) on Hopper-v5", created.output)[1])
    tree_hash = re.search(r"tree_sha256 ([0-9a-f]{64})", created.output)[1]
    # the tree to train with, and its hash: the file's own, as sha256sum gives it
    assert hashlib.sha256(tree_file.read_bytes()).hexdigest() == tree_hash
    assert tree_digest(load_tree(tree_file)) == tree_hash
    shown = client.get(f"/api/experiments/{experiment}", headers=ADMIN).json()
    assert shown["spec"]["tree_sha256"] == tree_hash
    onnx = _write(tmp_path, "advised.onnx", policy(seed=51))
    norm = _write(tmp_path, "norm.npz", obs_norm())
    imported = run(
        "agents", "import", onnx, "--experiment", experiment, "--arm", "advised", "--seed", "0",
        "--algorithm", "cleanrl ppo", "--steps", "50000", "--tree-sha256", tree_hash,
        "--obs-norm", norm,
    )  # fmt: skip
    assert imported.exit_code == 0, imported.output
    assert f"advised seed 0 imported into experiment {experiment} (onnx" in imported.output
    zipped = _write(tmp_path, "ppo.zip", sb3_zip(seed=3))
    converted = run(
        "agents", "import", zipped, "--experiment", experiment, "--arm", "baseline",
        "--algorithm", "sb3 PPO", "--activation", "relu",
    )  # fmt: skip
    assert converted.exit_code == 0, converted.output
    assert "(sb3-zip, ONNX sha256" in converted.output
    runs = client.get(f"/api/experiments/{experiment}", headers=ADMIN).json()["runs"]
    baseline = next(r for r in runs if r["role"] == "baseline")
    imported_as = baseline["imported"]
    assert imported_as["declared"] == {  # steps and seed from the save's plain fields
        "algorithm": "sb3 PPO",
        "steps": 2048,
        "seed": 3,
        "tree_sha256": None,
    }
    assert imported_as["metadata"]["activation"] == "relu" and imported_as["sb3"]["n_envs"] == 1
    assert "policy_class" not in imported_as["sb3"]  # a pickled field: never read
    state = client.app.state
    root = state.job_settings.runs_root(state.runtime.settings) / "policies"
    stored = (root / f"{imported_as['onnx_sha256']}.onnx").read_bytes()
    assert not stored.startswith(b"PK")  # only the ONNX is stored, never the zip


@pytest.mark.parametrize(
    ("name", "data", "options", "says"),
    [
        ("corrupt.onnx", b"\x08\x07garbage", [], "not an ONNX model"),
        ("exp.onnx", forbidden_op(), [], "uses op 'Exp', which is not allowed"),
        ("external.onnx", external_data(), [], "has external data"),
        ("sizes.onnx", wrong_sizes(), [], "not float32 [N, obs_dim=11]"),
        ("no-env.onnx", policy(env_id=None), [], "no env id"),
        ("walker.onnx", policy(env_id=None), ["--env-id", "Walker2d-v5"], "is for Walker2d-v5"),
        ("walker.onnx", policy(env_id="Walker2d-v5"), [], "is for Walker2d-v5"),
        ("act.onnx", policy(), ["--activation", "tanh"], "--activation is for an SB3 zip"),
        ("act.zip", sb3_zip(), ["--activation", "gelu"], "unknown activation 'gelu'"),
        (
            "sac.zip",
            sb3_zip(extra={"actor.mu.weight": torch.zeros(3, 8)}),
            [],
            "not an SB3 MlpPolicy",
        ),
        ("arm.onnx", policy(), ["--arm", "champion"], "unknown arm 'champion'"),
        ("tree.onnx", policy(), ["--tree-sha256", "f" * 64], "trains without advice"),
        ("missing.onnx", None, [], "No such file"),
    ],
)
def test_bad_input_exits_2_and_stores_nothing(
    client: TestClient,
    study: dict[str, Any],
    run,
    tmp_path: Path,
    name: str,
    data: bytes | None,
    options: list[str],
    says: str,
) -> None:
    experiment = create_external(client, study["id"])
    path = tmp_path / name if data is None else _write(tmp_path, name, data)
    before = _state(client)
    result = run(
        "agents", "import", path, "--experiment", experiment["id"], "--arm", "baseline",
        "--seed", "0", "--algorithm", "x", "--steps", "10", *options,
    )  # fmt: skip
    assert result.exit_code == 2, result.output
    assert says in result.stderr and result.stderr.startswith("acv: error: "), result.stderr
    assert _state(client) == before


def test_a_file_over_its_cap_is_refused_before_it_is_read(
    client: TestClient, study: dict[str, Any], run, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(agents_cli, "OnnxLimits", lambda: OnnxLimits(max_bytes=100))
    experiment = create_external(client, study["id"])
    path = _write(tmp_path, "big.onnx", policy())
    before = _state(client)
    result = run(
        "agents", "import", path, "--experiment", experiment["id"], "--arm", "baseline",
        "--seed", "0", "--algorithm", "x", "--steps", "10",
    )  # fmt: skip
    assert result.exit_code == 2 and "over the limit of 100 bytes" in result.stderr
    assert _state(client) == before


def test_the_cli_refuses_an_experiment_that_is_not_external(
    client: TestClient, study: dict[str, Any], run, tmp_path: Path
) -> None:
    own = run("agents", "experiment", "--study", study["id"])
    assert own.exit_code == 2 and "give participant_id" in own.stderr
    experiments = client.get("/api/experiments", headers=ADMIN).json()
    for where in (tmp_path / "no-such-folder" / "tree.json", tmp_path):
        refused = run(
            "agents", "experiment", "--study", study["id"], "--teacher", "good", "--tree-out", where
        )  # fmt: skip
        assert refused.exit_code == 2 and "cannot write a file there" in refused.stderr
    assert client.get("/api/experiments", headers=ADMIN).json() == experiments  # none stored
    path = _write(tmp_path, "p.onnx", policy())
    missing = run("agents", "import", path, "--experiment", 999_999, "--arm", "baseline")
    assert missing.exit_code == 2 and "experiment 999999 not found" in missing.stderr
