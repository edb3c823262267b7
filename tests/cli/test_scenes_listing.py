"""`voxfield scenes` lists every scene name the command line accepts without a file, each
description starting in one column."""

from __future__ import annotations

import re

from voxfield.cli.main import main
from voxfield.scene.builtin import BUILTIN_SCENES
from voxfield.scene.terrain import RECIPES
from voxfield.scene.terrain.dem import SAMPLE_DEMS


def test_the_listing_names_every_builtin_recipe_and_sample_dem(capsys):
    assert main(["scenes"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("  ")]
    names = [line.split()[0] for line in rows]
    assert names == ([f"builtin:{n}" for n in sorted(BUILTIN_SCENES)]
                     + [f"terrain:{n}" for n in RECIPES] + [f"dem:{n}" for n in SAMPLE_DEMS])
    starts = {re.match(r"  \S+\s+", line).end() for line in rows}
    assert len(starts) == 1, starts


def test_a_smooth_recipe_does_not_describe_its_noisy_original():
    for name, recipe in RECIPES.items():
        if name.endswith("-smooth"):
            assert "no per-column noise" in recipe.description
            assert "strong texture noise" not in recipe.description
