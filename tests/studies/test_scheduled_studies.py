"""Studies on a Dask scheduler: the same results as the plain loop, items cached as they land
so an interrupted batch resumes, and clean refusals of schedulers that name nothing."""

from __future__ import annotations

import json

import numpy as np
import pytest

from voxfield.cli import main
from voxfield.render.camera import orbit_camera
from voxfield.scene.builtin import BUILTIN_SCENES
from voxfield.studies.compare import run_compare
from voxfield.studies.report import StudyFolder
from voxfield.studies.sweep import run_sweep
from voxfield.svo.build import build_octree


@pytest.fixture(scope="module")
def octree():
    return build_octree(BUILTIN_SCENES["pillars"]())


@pytest.fixture(scope="module")
def camera(octree):
    return orbit_camera(*octree.voxel_bounds, size=20)


def _without_timing(value):
    """A report with wall-clock fields removed (they differ run to run by nature)."""
    if isinstance(value, dict):
        return {k: _without_timing(v) for k, v in value.items()
                if k not in ("seconds", "mrays_per_second", "folder", "written", "computed",
                             "reused")}
    if isinstance(value, list):
        return [_without_timing(v) for v in value]
    return value


def test_sweep_is_identical_on_every_scheduler(tmp_path, octree, camera, dask_client):
    reports = {}
    for label, scheduler in (("loop", None), ("threads", "threads"), ("cluster", dask_client)):
        reports[label] = run_sweep(octree, camera, tmp_path / label, decays=(0.1, 0.3),
                                   thresholds=(0.05, 0.2), scheduler=scheduler)
    assert _without_timing(reports["threads"]) == _without_timing(reports["loop"])
    assert _without_timing(reports["cluster"]) == _without_timing(reports["loop"])
    assert len(reports["loop"]["cells"]) == 4


def test_compare_is_identical_on_a_cluster(tmp_path, octree, camera, dask_client):
    loop = run_compare(octree, camera, tmp_path / "loop")
    cluster = run_compare(octree, camera, tmp_path / "cluster", scheduler=dask_client)
    assert _without_timing(cluster["rows"]) == _without_timing(loop["rows"])
    for name in ("reference", "adaptive", "error_aware"):
        a = (tmp_path / "loop" / f"{name}.png").read_bytes()
        assert (tmp_path / "cluster" / f"{name}.png").read_bytes() == a, name


class Failing:
    """An item that fails: a batch stopped part-way."""

    def __call__(self, shared):
        raise KeyboardInterrupt


def test_a_stopped_batch_keeps_what_landed_and_resumes(tmp_path):
    calls = []

    def value(k):
        def compute(shared):
            calls.append(k)
            return {"k": k, "shared": shared}, {"a": np.arange(k + 1)}
        return compute

    specs = [(f"item{k}", {"k": k}, value(k)) for k in range(3)]
    with pytest.raises(KeyboardInterrupt):
        StudyFolder(tmp_path, study="sweep").batch([*specs[:2], ("stop", {}, Failing()), specs[2]],
                                    shared=7)
    assert calls == [0, 1]
    folder = StudyFolder(tmp_path, study="sweep")
    results = folder.batch(specs, shared=7)
    assert calls == [0, 1, 2]  # only the item that never landed is computed again
    assert folder.reused == ["item0", "item1"] and folder.computed == ["item2"]
    assert [data["k"] for data, _ in results] == [0, 1, 2]
    np.testing.assert_array_equal(results[2][1]["a"], [0, 1, 2])
    # --fresh recomputes everything once, then trusts what this run wrote.
    fresh = StudyFolder(tmp_path, study="sweep", fresh=True)
    fresh.batch(specs, shared=7)
    assert fresh.computed == ["item0", "item1", "item2"]


def test_cli_studies_take_a_scheduler(tmp_path, capsys):
    out = tmp_path / "t"
    assert main(["--quiet", "study", "thresholds", "builtin:pillars", "--size", "12",
                 "--thresholds", "0.1,0.2", "--scheduler", "threads", "--out", str(out)]) == 0
    plain = tmp_path / "plain"
    assert main(["--quiet", "study", "thresholds", "builtin:pillars", "--size", "12",
                 "--thresholds", "0.1,0.2", "--out", str(plain)]) == 0
    a = json.loads((out / "results.json").read_text())
    b = json.loads((plain / "results.json").read_text())
    assert _without_timing(a) == _without_timing(b)
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "builtin:pillars", "--scheduler", "nowhere", "--out", str(tmp_path)])
    assert exc.value.code == 2
    assert "scheduler must be" in capsys.readouterr().err


def test_normalisation_study_is_identical_on_threads(tmp_path, octree, camera):
    from voxfield.studies.adaptive_normalisation import run_normalisation_study

    menger = build_octree(BUILTIN_SCENES["menger"]())
    scenes = {"pillars": (octree, camera),
              "menger": (menger, orbit_camera(*menger.voxel_bounds, size=20))}
    loop = run_normalisation_study(scenes, tmp_path / "loop")
    threads = run_normalisation_study(scenes, tmp_path / "threads", scheduler="threads")
    assert threads == loop
    assert [row["scene"] for row in loop["scenes"]] == ["pillars", "menger"]


def test_shadow_study_is_identical_on_threads(tmp_path):
    """``voxfield shadows --scheduler threads`` gives the plain run's report and images."""
    args = ["--quiet", "shadows", "--size", "12", "--light-samples", "2",
            "--reference-samples", "4", "--floor-samples", "2"]
    assert main([*args, "--out", str(tmp_path / "loop")]) == 0
    assert main([*args, "--scheduler", "threads", "--out", str(tmp_path / "threads")]) == 0
    loop = json.loads((tmp_path / "loop" / "results.json").read_text())
    threads = json.loads((tmp_path / "threads" / "results.json").read_text())
    assert _without_timing(threads) == _without_timing(loop)
    for name in ("reference", "distance", "error_aware"):
        assert ((tmp_path / "threads" / f"{name}.png").read_bytes()
                == (tmp_path / "loop" / f"{name}.png").read_bytes()), name
