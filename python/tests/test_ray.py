"""`deepfoids.ray`: `reproduce`'s stages as Ray tasks on a local Ray instance
(two CPUs), with the binary `cargo test` built (`target/debug/deepfoids`; set
DEEPFOIDS_BIN for another). The claim `seabream-cage` on the quick profile
× 0.02 trains three stages: the seabream pretraining, then two transfers
from it that may run at once."""

import json
import os
from pathlib import Path

import pytest

if os.environ.get("CI"):
    import ray  # .ci/run installs it: missing is a failure there
else:
    ray = pytest.importorskip("ray")

from deepfoids.ray import plan, reproduce  # noqa: E402

BIN = Path(
    os.environ.get(
        "DEEPFOIDS_BIN", Path(__file__).resolve().parents[2] / "target" / "debug" / "deepfoids"
    )
)
OPTIONS = [
    "--profile", "quick", "--only", "seabream-cage",
    "--budget-scale", "0.02", "--eval-scale", "0.06", "--quiet",
]  # fmt: skip
STAGES = ["pretrain-seabream", "transfer-seabream_default", "transfer-seabream_cube5"]


@pytest.fixture
def binary():
    if not BIN.is_file():
        if os.environ.get("CI"):
            pytest.fail(f"{BIN} is missing: run `cargo test` first")
        pytest.skip(f"{BIN} is missing: run `cargo test` first")
    return str(BIN)


def test_the_plan_names_each_stage_and_what_it_starts_from(binary, tmp_path):
    stages = plan(binary, tmp_path / "repro", [*OPTIONS, "--seeds", "3,4"])
    assert [(s["seed"], s["stage"]) for s in stages] == [(3, n) for n in STAGES] + [
        (4, n) for n in STAGES
    ]
    by_name = {s["stage"]: s for s in stages}
    assert by_name["pretrain-seabream"]["init_from"] == []
    assert by_name["transfer-seabream_cube5"]["init_from"] == ["pretrain-seabream"]
    assert by_name["transfer-seabream_cube5"]["phase"] == "transfer"
    assert not (tmp_path / "repro").exists(), "the plan writes nothing"


def test_a_reproduction_runs_as_ray_tasks_in_the_local_layout(binary, tmp_path):
    out = tmp_path / "repro"
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        reports = reproduce(out, OPTIONS, binary=binary, cpus_per_stage=1)
    finally:
        ray.shutdown()
    assert reports == [out / "report" / "REPORT.md"]
    assert "seabream-cage" in reports[0].read_text()
    finished = {}
    for stage in STAGES:
        state = out / "s0" / stage / "final" / "state.json"
        assert '"budget": 4000' in state.read_text(), stage
        record = json.loads((out / "s0" / stage / "reproduce.json").read_text())
        assert record["timed"] and record["agent_steps"] >= 4000, record
        finished[stage] = state.stat().st_mtime
    # Each transfer began after the pretraining it starts from had finished.
    for stage in STAGES[1:]:
        began = (out / "s0" / stage / "config.toml").stat().st_mtime
        assert began >= finished["pretrain-seabream"], stage
