"""The 3D march's step range: ``1 / max_steps`` (a shorter step stops at its step cap before
it has marched one voxel) to one voxel; ``LightFieldOptions`` refuses the rest."""

from __future__ import annotations

import numpy as np
import pytest
from lf_helpers import CORNELL_PROBE, one_probe

from voxfield.errors import VoxfieldError
from voxfield.lightfield import MISS, UNKNOWN, LightFieldOptions, trace_single


@pytest.mark.parametrize("step", [1e-6, 1e-30, 1e308, 2.0, 0.0, -0.25, float("nan"),
                                  float("inf"), 1 / 4096 * (1 - 1e-9), 1 + 1e-9])
def test_steps_outside_the_range_are_refused_with_it(step):
    with pytest.raises(VoxfieldError, match=r"must be 0\.000244141\.\.1 voxels"):
        LightFieldOptions(marcher="march3d", step=step)


def test_the_shortest_step_taken_marches_one_voxel_and_no_shorter_one_does(cornell):
    """In open space a march of ``max_steps`` points at the shortest step taken answers a
    one-voxel ray (MISS); the same step with one point fewer is refused, and would have
    stopped short at its cap (UNKNOWN before the voxel's end)."""
    packed = one_probe(cornell, CORNELL_PROBE, 16)
    origin = CORNELL_PROBE[None] + [0.5, 0.25, 0.0]  # the probe's room is empty here
    direction = np.array([[0.3, -0.2, 0.9]])
    taken = LightFieldOptions(marcher="march3d", step=0.25, max_steps=4)
    assert LightFieldOptions(marcher="march3d", step=1.0, max_steps=1).step == 1.0
    with pytest.raises(VoxfieldError, match="0.333333..1 voxels"):
        LightFieldOptions(marcher="march3d", step=0.25, max_steps=3)
    hits = trace_single(packed, 0, origin, direction, taken, tmax=1.0)
    assert hits.kind[0] == MISS and hits.t[0] == 1.0 and hits.steps[0] == 4
    short = LightFieldOptions(marcher="march3d", step=0.25, max_steps=4)
    object.__setattr__(short, "max_steps", 3)  # what the check refuses, past it
    hits = trace_single(packed, 0, origin, direction, short, tmax=1.0)
    assert hits.kind[0] == UNKNOWN and hits.t[0] < 1.0
