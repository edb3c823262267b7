"""The EA thesis's shadow-ray test scene (§3.2.2, fig. 3.4), built procedurally.

A 32³ Cornell-style box (red left wall, green right wall, white elsewhere) stands in the
middle of a large floor. An emissive patch sits in its back wall; its front wall is a grid of
1-voxel bars around 1-voxel gaps, so a quarter of the light leaves the box and falls on the
floor in front of it. One LOD coarser every 2×2 cell of the grid holds a bar, so the grid
becomes a closed plane (fig. 3.4b) and a shadow ray sampling it there sees no light at all.

Layout (finest-voxel units, +y up, the light shines towards +z):

- floor: ``FLOOR_THICKNESS`` voxels thick, ``floor_size`` wide in x and z, top at
  ``y = FLOOR_THICKNESS``; a thickness of 4 keeps the floor's LOD-1 and LOD-2 nodes flush with
  its top, so coarse shadow rays leaving the floor do not hit the floor itself;
- box: ``[x0, x0 + 32) × [4, 36) × [z0, z0 + 32)``, centred on the floor, corners at multiples
  of 16; walls one voxel thick, the back wall two (the light is set into its inner layer, so
  it emits into the box only);
- grid: the front layer ``z = z0 + 31``; a voxel inside the frame is a gap when both its x
  and y offsets from the box corner are odd (15 × 15 gaps);
- light: ``LIGHT_SIZE``² voxels in the back wall's inner layer, centred in x, upper half in y.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from voxfield.checks import is_integer
from voxfield.errors import VoxfieldError
from voxfield.scene.voxel_scene import VoxelScene

BOX_SIZE = 32
FLOOR_THICKNESS = 4
LIGHT_SIZE = 8
#: Emitted radiance of the light, chosen so the lit floor in front of the box reads about
#: 0.2–0.6 (linear) before clamping: the box passes a quarter of the light through the grid.
LIGHT_RADIANCE = 600.0

WHITE = (0.73, 0.73, 0.73)
RED = (0.63, 0.06, 0.05)
GREEN = (0.14, 0.45, 0.09)
GRID = (0.55, 0.55, 0.6)
FLOOR = (0.7, 0.68, 0.62)


@dataclass(frozen=True)
class ShadowBoxLayout:
    """Where the parts of the scene are, in the scene's (= the octree's) voxel coordinates."""

    floor_size: int
    box_min: tuple[int, int, int]

    @property
    def floor_top(self) -> int:
        """The ``y`` of the floor's upper face."""
        return FLOOR_THICKNESS

    @property
    def box_max(self) -> tuple[int, int, int]:
        return tuple(c + BOX_SIZE for c in self.box_min)

    @property
    def grid_z(self) -> int:
        """The ``z`` of the grid layer; its outer face is at ``grid_z + 1``."""
        return self.box_min[2] + BOX_SIZE - 1

    @property
    def light_min(self) -> tuple[int, int, int]:
        x0, y0, z0 = self.box_min
        return (x0 + (BOX_SIZE - LIGHT_SIZE) // 2, y0 + BOX_SIZE - 6 - LIGHT_SIZE, z0 + 1)

    def behind_grid(self, length: int = 64) -> tuple[tuple[float, float], tuple[float, float]]:
        """The floor rectangle ``((x0, x1), (z0, z1))`` in front of the grid, as wide as the
        box and ``length`` voxels deep: where the light through the grid lands."""
        x0 = float(self.box_min[0])
        z0 = float(self.grid_z + 1)
        return (x0, x0 + BOX_SIZE), (z0, min(z0 + length, float(self.floor_size)))


def shadow_box_layout(floor_size: int = 256) -> ShadowBoxLayout:
    """The layout of ``shadow_box(floor_size)``."""
    if not is_integer(floor_size) or floor_size < 2 * BOX_SIZE or floor_size % 32:
        raise VoxfieldError(
            f"the shadow box needs a floor size that is a multiple of 32 and at least "
            f"{2 * BOX_SIZE}, got {floor_size}"
        )
    corner = (floor_size - BOX_SIZE) // 2
    return ShadowBoxLayout(floor_size, (corner, FLOOR_THICKNESS, corner))


def _box_cells(layout: ShadowBoxLayout) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Voxel offsets inside the box, their colours and their emission."""
    n = BOX_SIZE
    x, y, z = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    left, right = x == 0, x == n - 1
    floor, ceiling = y == 0, y == n - 1
    back = z <= 1
    front = z == n - 1
    frame = left | right | floor | ceiling
    gap = front & ~frame & (x % 2 == 1) & (y % 2 == 1)
    solid = frame | back | (front & ~gap)
    cells = np.argwhere(solid)
    color = np.tile(np.asarray(WHITE, np.float32), (len(cells), 1))
    cx, cy, cz = cells.T
    color[(cz == n - 1) & (cx > 0) & (cx < n - 1) & (cy > 0) & (cy < n - 1)] = GRID
    color[cx == 0] = RED
    color[cx == n - 1] = GREEN
    lx, ly, lz = (a - b for a, b in zip(layout.light_min, layout.box_min, strict=True))
    light = (
        (cz == lz) & (cx >= lx) & (cx < lx + LIGHT_SIZE) & (cy >= ly) & (cy < ly + LIGHT_SIZE)
    )
    emission = np.zeros_like(color)
    emission[light] = LIGHT_RADIANCE
    color[light] = 1.0
    return cells + np.asarray(layout.box_min), color, emission


def shadow_box(floor_size: int = 256) -> VoxelScene:
    """EA fig. 3.4 shadow-ray test: 32³ Cornell box, light at the back, 1-voxel front grid.

    The box stands in the middle of a ``floor_size``² floor (layout: the module docstring).
    """
    layout = shadow_box_layout(floor_size)
    fx, fy, fz = np.meshgrid(
        np.arange(floor_size), np.arange(FLOOR_THICKNESS), np.arange(floor_size), indexing="ij"
    )
    floor = np.stack([fx.ravel(), fy.ravel(), fz.ravel()], axis=1)
    floor_color = np.tile(np.asarray(FLOOR, np.float32), (len(floor), 1))
    box, box_color, box_emission = _box_cells(layout)
    return VoxelScene(
        np.concatenate([floor, box]),
        np.concatenate([floor_color, box_color]),
        emission=np.concatenate([np.zeros_like(floor_color), box_emission]),
        name="shadowbox",
    )
