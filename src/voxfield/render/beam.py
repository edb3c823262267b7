"""Beam bounds for an image: where the primary rays of each pixel block may start.

The bound itself (``kernels.beam``) is exact: starting there changes no hit, distance or
normal, only the traversal steps. The beam's own search steps are part of the render's cost,
so they are shared out over the pixels of their block and added to the step map.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numba
import numpy as np

from voxfield.kernels.beam import add_block_shares, beam_map
from voxfield.kernels.camera_rays import PINHOLE, pixel_cone
from voxfield.kernels.column_raster import direction_limits, draw_cell_boxes
from voxfield.kernels.traversal import cone_width
from voxfield.render.camera import Camera
from voxfield.svo.octree import Octree

#: Block sides of the beam passes, coarse to fine, each starting at its parent's bound: one
#: 8×8 pass for one ray per pixel; with several rays per pixel a 4×4 pass pays off as well
#: (measured on the mountain terrain, benchmarks/bench_traversal.py).
BEAM_BLOCKS = (8,)
BEAM_BLOCKS_SUPERSAMPLED = (8, 4)


@dataclass
class Beam:
    """Start bounds per ``block``×``block`` pixel block (``bound[by, bx]``, 0 where unknown)
    and the search steps of every pass, shared out over the pixels (``pixel_steps``)."""

    bound: np.ndarray
    block: int
    steps: list = field(default_factory=list)  # (block side, steps per block) per pass
    seconds: float = 0.0

    @property
    def total_steps(self) -> int:
        return int(sum(s.sum() for _, s in self.steps))

    def pixel_steps(self, pixels: np.ndarray, width: int) -> np.ndarray:
        """Every pass's search steps shared out over the listed pixels (flat indices) of
        their block: an equal part each, the remainder one by one in list order."""
        pixels = np.asarray(pixels, np.int64)
        total = np.zeros(len(pixels), np.int64)
        rows, cols = np.divmod(pixels, width)
        for block, steps in self.steps:
            blocks = (rows // block) * steps.shape[1] + cols // block
            counts = np.bincount(blocks, minlength=steps.size)
            share, remainder = np.divmod(steps.reshape(-1), np.maximum(counts, 1))
            order = np.argsort(blocks, kind="stable")
            rank = np.empty(len(pixels), np.int64)
            starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
            rank[order] = np.arange(len(pixels)) - np.repeat(starts, counts)
            total += share[blocks] + (rank < remainder[blocks])
        return total

    def image_steps(self, height: int, width: int) -> np.ndarray:
        """``pixel_steps`` of every pixel of the image in row-major order, as an (H, W) map:
        a pixel's rank in its block is its row-major position there, so no sort is needed."""
        total = np.zeros((height, width), np.int64)
        for block, steps in self.steps:
            block_heights = np.minimum(block, height - np.arange(steps.shape[0]) * block)
            block_widths = np.minimum(block, width - np.arange(steps.shape[1]) * block)
            share, remainder = np.divmod(steps, np.outer(block_heights, block_widths))
            add_block_shares(total, block, share.astype(np.int64), remainder.astype(np.int64))
        return total


def blocks_of(camera: Camera, block: int) -> tuple[int, int]:
    return -(-camera.height // block), -(-camera.width // block)


def no_beam(camera: Camera) -> Beam:
    """Every ray starts at the camera."""
    return Beam(np.zeros((1, 1)), max(camera.width, camera.height))


def plan_beam(
    octree: Octree, camera: Camera, *, stop_level: int, cone_radius: float = 0.0,
    cone_spread: float = 0.0, pixels: np.ndarray | None = None,
    blocks: tuple[int, ...] = BEAM_BLOCKS,
) -> Beam:
    """Beam bounds for the blocks holding ``pixels`` (all blocks when None) of rays that
    stop at ``stop_level`` or where a node is no larger than
    ``cone_radius + cone_spread · t``; one pass per block side in ``blocks``."""
    beam = no_beam(camera)
    threads = numba.get_num_threads()
    # No blocks: compiles (or loads) the kernel outside the timing, as ``run_in_bands`` does
    # for a render's (a first render reported its rays at a hundredth of their speed).
    beam_map(camera.params, camera.width, camera.height, 1, octree.inner_nodes, octree.depth,
             stop_level, float(cone_radius), float(cone_spread), np.zeros((0, 0), bool),
             beam.bound, beam.block, np.empty((0, 0)), np.empty((0, 0), np.int64), threads)
    start = time.perf_counter()
    for block in blocks:
        shape = blocks_of(camera, block)
        if pixels is None:
            wanted = np.ones(shape, bool)
        else:
            wanted = np.zeros(shape, bool)
            rows, cols = np.divmod(np.asarray(pixels, np.int64), camera.width)
            wanted[rows // block, cols // block] = True
        bound = np.empty(shape)
        steps = np.empty(shape, np.int64)
        beam_map(camera.params, camera.width, camera.height, block, octree.inner_nodes,
                 octree.depth, stop_level, float(cone_radius), float(cone_spread), wanted,
                 beam.bound, beam.block, bound, steps, threads)
        beam.bound = bound
        beam.block = block
        beam.steps.append((block, steps))
    beam.seconds = time.perf_counter() - start
    return beam


def primary_beam(
    octree: Octree, camera: Camera, *, stop_level: int, cone_scale: float = 0.0,
    side: int = 1, pixels: np.ndarray | None = None, enabled: bool = True,
) -> Beam:
    """The beam every primary-ray renderer uses, so that all count steps alike: rays that
    stop at ``stop_level`` or, with ``cone_scale`` > 0, where a node is no larger than
    ``cone_scale`` footprints of a ``1/side`` sub-pixel."""
    if not enabled:
        return no_beam(camera)
    radius, spread = pixel_cone(camera.params, camera.height)
    blocks = BEAM_BLOCKS if side == 1 else BEAM_BLOCKS_SUPERSAMPLED
    return plan_beam(octree, camera, stop_level=stop_level,
                     cone_radius=radius * cone_scale / side,
                     cone_spread=spread * cone_scale / side, pixels=pixels, blocks=blocks)


#: Pixels per drawn cell: the raster draws the finest pyramid level with at most one cell
#: per this many pixels. Finer cells start rays nearer their hits but cost more to draw;
#: on the mountain terrain (512² image, one ray a pixel, 2 threads, the drawing included)
#: one cell per 4 pixels took 0.84-0.89× the time of the 8×8 beam at 2048² (top, 45°), one
#: per pixel 0.89-0.91× and one per 16 pixels 0.86-0.92×.
RASTER_CELL_PIXELS = 4
#: The same for supersampled pixels, whose rays share the drawing: with 16 rays a pixel one
#: cell per pixel took 0.84× (top) and 0.80× (45°) the time of the 8×8 and 4×4 beam, one
#: per 4 pixels 0.92× and 0.89×, four cells a pixel 0.81× and 0.84×.
RASTER_CELL_PIXELS_SUPERSAMPLED = 1


def raster_beam(camera: Camera, columns, *, stop_level: int, depth: int,
                whole_pixel: bool = False) -> Beam | None:
    """Per-pixel start bounds from the column-top pyramid drawn into the image
    (``kernels.column_raster``), for rays at the fixed level ``stop_level`` of an octree of
    ``depth`` levels, or None where it cannot draw them: no pyramid, a camera other than a
    pinhole, or a cell box across the eye plane (a camera among the columns).

    The bound holds for the ray through the pixel's centre, or with ``whole_pixel`` for
    every ray through the pixel (supersampled pixels, refined ones). It draws the finest
    level with a cell per ``RASTER_CELL_PIXELS`` pixels or fewer
    (``RASTER_CELL_PIXELS_SUPERSAMPLED`` for whole pixels), not finer than the sampled
    nodes. Its steps are the cells drawn, shared out over the image like
    one beam block's."""
    level = raster_level(camera, columns, stop_level=stop_level, depth=depth,
                         whole_pixel=whole_pixel)
    if level is None:
        return None
    node_level = depth - min(stop_level, depth)
    cam = camera.params
    # No cells: compiles (or loads) the kernel outside the timing, as ``plan_beam`` does.
    draw_cell_boxes(cam, np.eye(3), 1, 1, columns.tops, columns.floors, 0, 0, 0, 0, 0, 0.0,
                    np.ones((1, 1, 3)), 1, np.full((1, 1, 1), np.inf), np.zeros(1, np.int64))
    direction_limits(cam, 1, 1, 0.0)
    start = time.perf_counter()
    reach = 0.5 if whole_pixel else 0.0
    limits = direction_limits(cam, camera.width, camera.height, reach)
    basis = np.array([cam[4:7], cam[7:10], cam[10:13]]).T  # columns forward, right, up
    to_camera = np.linalg.inv(basis)
    parts = numba.get_num_threads()
    nearest = np.full((parts, camera.height, camera.width), np.inf)
    drawn = np.zeros(parts, np.int64)
    ok = draw_cell_boxes(cam, to_camera, camera.width, camera.height, columns.tops,
                         columns.floors, int(columns.level_offset[level]),
                         int(columns.level_width[level]), int(columns.level_depth[level]),
                         level, node_level, reach, limits, parts, nearest, drawn)
    if not ok:
        return None
    bound = nearest.min(axis=0) if parts > 1 else nearest[0]
    beam = Beam(bound, 1, seconds=time.perf_counter() - start)
    whole = max(camera.width, camera.height)
    beam.steps.append((whole, np.array([[int(drawn.sum())]], np.int64)))
    return beam


def can_draw(camera: Camera, columns) -> bool:
    """Whether ``raster_beam`` can draw any level for this camera: a pinhole and a pyramid
    (a probe's octahedral map is not a projection of boxes to the image)."""
    return camera.kind == PINHOLE and columns.level_width.shape[0] > 0


def raster_level(camera: Camera, columns, *, stop_level: int, depth: int,
                 whole_pixel: bool) -> int | None:
    """The pyramid level ``raster_beam`` draws for these arguments, or None where it draws
    nothing (before it tries the camera's eye plane)."""
    levels = columns.level_width.shape[0]
    node_level = depth - min(stop_level, depth)
    if not can_draw(camera, columns) or node_level >= levels:
        return None
    pixels = camera.width * camera.height
    cell_pixels = RASTER_CELL_PIXELS_SUPERSAMPLED if whole_pixel else RASTER_CELL_PIXELS
    level = node_level
    while (level + 1 < levels
           and columns.level_width[level] * columns.level_depth[level] * cell_pixels > pixels):
        level += 1
    return level


def raster_cells(columns, level: int) -> int:
    """The cells ``raster_beam`` draws at ``level``, its steps: the level's occupied ones."""
    first = int(columns.level_offset[level])
    count = int(columns.level_width[level]) * int(columns.level_depth[level])
    return int(np.count_nonzero(columns.tops[first:first + count]))


def pixel_start_bounds(octree: Octree, camera: Camera, columns, *, stop_level: int,
                       cone_scale: float = 0.0, side: int = 1, whole_pixel: bool = False,
                       enabled: bool = True) -> Beam:
    """Where each pixel's rays start, the one choice the primary renderers share: at their
    pixel's bound from the pyramid ``columns`` drawn into the image (``raster_beam``,
    ``whole_pixel`` as there), where it can be drawn; else at their block's beam bound
    (``primary_beam``). Cone-LOD rays (``cone_scale`` > 0) take the bound drawn for the
    largest nodes their cones accept anywhere in the octree (``coarsest_cone_level``): on
    the 2048² mountain terrain (512²) their renders took 0.73-0.76× the block beam's time
    from the top, 0.79-0.81× at 45°, with one ray a pixel or 16, the same pixels."""
    if enabled and can_draw(camera, columns):
        drawn_stop = stop_level
        if cone_scale > 0.0:
            drawn_stop = octree.depth - coarsest_cone_level(octree, camera, cone_scale, side)
        bounds = raster_beam(camera, columns, stop_level=drawn_stop, depth=octree.depth,
                             whole_pixel=whole_pixel)
        if bounds is not None:
            return bounds
    return primary_beam(octree, camera, stop_level=stop_level, cone_scale=cone_scale,
                        side=side, enabled=enabled)


def coarsest_cone_level(octree: Octree, camera: Camera, cone_scale: float, side: int) -> int:
    """The level of the largest node the cone of a ``1/side`` sub-pixel's ray (``cone_scale``
    footprints wide, ``kernels.traversal.cone_width``) can accept in ``octree``: a node of
    side ``2^k`` lies in the voxels' box rounded out to ``2^k``, so the ray enters it no
    farther than that box's farthest corner, and a cone no wider there accepts no such node.
    Boxes of the pyramid's cells rounded to that level then hold every node a cone-LOD ray
    can hit, and its drawn bound starts every such ray before its hit: no node it accepts
    (none larger) holds it there, so the octree from the bound judges each node at its
    entry, as from the eye (``kernels.cone_walk``'s contract)."""
    radius, spread = pixel_cone(camera.params, camera.height)
    radius *= cone_scale / side
    spread *= cone_scale / side
    eye = np.asarray(camera.params[1:4], np.float64)
    lo, hi = (np.asarray(b, np.float64) for b in octree.voxel_bounds)
    nodes = np.ldexp(1.0, np.arange(1, octree.depth + 1))[:, None]
    # The farthest of a box's corners takes the farther face on each axis.
    reach = np.maximum((np.floor(lo / nodes) * nodes - eye) ** 2,
                       (np.ceil(hi / nodes) * nodes - eye) ** 2)
    farthest = np.sqrt(reach.sum(axis=1))
    coarsest = 0
    for level, (node, far) in enumerate(zip(nodes[:, 0], farthest, strict=True), start=1):
        # (A margin over the rounding of the traversal's own entry times.)
        if node <= cone_width(radius, spread, float(far) * (1.0 + 1e-9) + 1e-6):
            coarsest = level
    return coarsest
