"""``voxfield study probe-resolution`` resumes like the other studies: every probe bake is an
item of its folder, so a rerun after Ctrl-C bakes only what was left and writes the same
results as a run that was never stopped; a rerun with another option bakes again only the
bakes that option changes."""

from __future__ import annotations

import dataclasses
import json

import pytest

import voxfield.studies.probe_resolution_study as study
from voxfield.cli import main

#: 2 map sizes × (reference + 3 cheap bakers) × 2 probes.
BAKES = 16


def _command(out, *more):
    return ["study", "probe-resolution", "builtin:cornell", "--grid", "2x1x1",
            "--resolutions", "8,16", "--quiet", "--out", str(out), *more]


@pytest.fixture
def bakes(monkeypatch):
    """The study's bakes, counted, with seconds that follow from the bake alone (a clock's
    would differ between any two runs), and a Ctrl-C injected at bake ``stop_at``."""
    real = study.bake_probe
    state = {"calls": [], "stop_at": None}

    def bake(octree, position, options, **kwargs):
        if len(state["calls"]) + 1 == state["stop_at"]:
            state["stop_at"] = None
            raise KeyboardInterrupt
        state["calls"].append((options.renderer, options.resolution, tuple(position)))
        maps = real(octree, position, options, **kwargs)
        cost = dataclasses.replace(maps.cost, radiance_seconds=maps.cost.radiance_rays / 3e7,
                                   geometry_seconds=maps.cost.geometry_rays / 7e7)
        return dataclasses.replace(maps, cost=cost)

    monkeypatch.setattr(study, "bake_probe", bake)
    return state


def _results(out) -> dict[str, bytes]:
    return {name: (out / name).read_bytes() for name in ("results.json", "results.md")}


def test_a_rerun_after_ctrl_c_bakes_only_what_was_left(tmp_path, bakes, capsys):
    clean = tmp_path / "clean"
    assert main(_command(clean)) == 0
    assert len(bakes["calls"]) == BAKES
    expected = _results(clean)

    stopped = tmp_path / "stopped"
    bakes["calls"].clear()
    bakes["stop_at"] = 7
    assert main(_command(stopped)) == 130
    assert "interrupted" in capsys.readouterr().err
    finished = list(bakes["calls"])
    assert len(finished) == 6

    bakes["calls"].clear()
    assert main(_command(stopped)) == 0
    assert len(bakes["calls"]) == BAKES - 6
    assert not set(finished) & set(bakes["calls"])  # no finished bake was baked again
    assert _results(stopped) == expected

    bakes["calls"].clear()  # a finished study reruns from its items alone
    assert main(_command(stopped)) == 0
    assert bakes["calls"] == [] and _results(stopped) == expected


def test_a_rerun_with_another_threshold_bakes_only_the_error_aware_probes(tmp_path, bakes):
    out = tmp_path / "study"
    assert main(_command(out)) == 0
    bakes["calls"].clear()
    assert main(_command(out, "--threshold", "0.0001")) == 0
    assert {renderer for renderer, _, _ in bakes["calls"]} == {"error-aware"}
    assert len(bakes["calls"]) == 4
    report = json.loads((out / "results.json").read_text())
    assert report["threshold"] == 0.0001
    fresh = tmp_path / "fresh"
    bakes["calls"].clear()
    assert main(_command(fresh, "--threshold", "0.0001")) == 0
    assert _results(out) == _results(fresh)


def test_fresh_bakes_everything_again(tmp_path, bakes):
    out = tmp_path / "study"
    assert main(_command(out)) == 0
    bakes["calls"].clear()
    assert main(_command(out, "--fresh")) == 0
    assert len(bakes["calls"]) == BAKES


def test_a_damaged_bake_is_baked_again(tmp_path, bakes):
    out = tmp_path / "study"
    assert main(_command(out)) == 0
    expected = _results(out)
    (damaged, *_) = sorted((out / "items").glob("bake-adaptive-16-probe1-*.npz"))
    damaged.write_bytes(damaged.read_bytes()[:50])
    bakes["calls"].clear()
    assert main(_command(out)) == 0
    assert [(r, s) for r, s, _ in bakes["calls"]] == [("adaptive", 16)]
    assert _results(out) == expected
