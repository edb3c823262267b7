"""An octree lit again in place kept its earlier bakes' ``previews`` as they were, naming
files the new bake had overwritten (the sheet) or that were gone, or that show a channel it
replaced: the record pointed at pictures of another bake. Each listed file must still be
the very file that bake wrote."""

from __future__ import annotations

import argparse
import json
import warnings

from voxfield.cli.cmd_light import register as add_light_parser


def _light(*argv: str) -> dict:
    parser = argparse.ArgumentParser()
    add_light_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["light", *argv])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the notes are another test's
        assert args.func(args) == 0
    out = [argv[k + 1] for k, a in enumerate(argv) if a == "--out"][0]
    return json.loads(open(out.removesuffix(".npz") + ".json", encoding="utf-8").read())


def _pictures(folder) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.glob("*.png")}


def _assert_previews_show_their_bakes(record: dict, written: list[dict], folder) -> None:
    """Every preview an earlier bake lists is byte for byte what that bake wrote."""
    for bake in record.get("earlier_bakes", []):
        for name in bake.get("previews", {}):
            wrote = next(w for w in written if w["seed"] == bake["seed"])["pictures"]
            assert (folder / name).read_bytes() == wrote[name], (bake["seed"], name)


def test_previews_of_earlier_bakes_name_only_files_that_still_show_them(tmp_path):
    out = tmp_path / "lit.npz"
    quick = ["--sky-rays", "0", "--shadow-rays", "1", "--preview-size", "8",
             "--out", str(out), "--quiet"]
    bakes = []  # each bake's seed (to tell them apart) and the pictures it wrote

    def bake(scene, times, seed, *more):
        record = _light(scene, "--times", times, "--seed", str(seed), *quick, *more)
        if "--no-preview" not in more:
            bakes.append({"seed": seed, "pictures": _pictures(tmp_path)})
        return record

    bake("builtin:sphere", "noon=180,60;dawn=90,5", 1)
    # The sheet lit.png is written again: it shows evening now, not noon and dawn.
    record = bake(str(out), "evening=270,10", 2)
    assert record["earlier_bakes"][0]["previews"] == {
        "lit_noon.png": ["noon"], "lit_dawn.png": ["dawn"]}
    _assert_previews_show_their_bakes(record, bakes, tmp_path)
    # dawn baked again without previews: lit_dawn.png shows the dawn this octree lost.
    record = bake(str(out), "dawn=90,8", 3, "--no-preview")
    noon_bake = record["earlier_bakes"][-1]
    assert [s["name"] for s in noon_bake["suns"]] == ["noon"]
    assert noon_bake["previews"] == {"lit_noon.png": ["noon"]}
    assert "lit_dawn.png" in record["stale_previews"]
    _assert_previews_show_their_bakes(record, bakes, tmp_path)
    # A preview removed by hand is no longer listed.
    (tmp_path / "lit_noon.png").unlink()
    record = bake(str(out), "west=270,20", 4, "--no-preview")
    assert record["earlier_bakes"][-1]["previews"] == {}
    evening = next(b for b in record["earlier_bakes"] if b["seed"] == 2)
    assert evening["previews"] == {"lit_evening.png": ["evening"], "lit.png": ["evening"]}
    _assert_previews_show_their_bakes(record, bakes, tmp_path)


def test_previews_beside_the_octree_lit_are_not_claimed_for_its_copy_elsewhere(tmp_path):
    """Lit from one folder into another under the same name: the earlier bake's previews
    are beside the first octree, not the new one."""
    (tmp_path / "a").mkdir()
    first = tmp_path / "a" / "lit.npz"
    quick = ["--sky-rays", "0", "--shadow-rays", "1", "--preview-size", "8", "--quiet"]
    _light("builtin:sphere", "--times", "noon", *quick, "--out", str(first))
    copy = tmp_path / "b" / "lit.npz"
    record = _light(str(first), "--times", "dawn=90,5", *quick, "--out", str(copy))
    assert "previews" not in record["earlier_bakes"][0]
