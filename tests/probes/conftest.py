"""The small scene the probe storage and scale-out tests bake."""

from __future__ import annotations

import pytest

from voxfield.scene.builtin import cornell
from voxfield.svo.build import build_octree


@pytest.fixture(scope="session")
def octree():
    """A 16³ Cornell box: rooms, occluders and colour, baked in well under a second."""
    return build_octree(cornell(16))
