"""Batch ray queries: arbitrary rays, closest or any hit (tests, oracles, benchmarks, probes).

Every ``threads`` worker claims runs of ``RAY_RUN`` rays from the call's queue
(``scheduling.claim_items``) until none is left, as renders claim their pixels: a list in
image order (its sky rows first, cheap misses) or one a neighbour's process slows keeps
both threads busy to the end, where ``prange``'s one contiguous half a thread left one
idle. Which thread traces a ray never changes its result.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from voxfield.kernels.borrowing import borrowing
from voxfield.kernels.lane_walk import (
    LANE_WALK_PAYS,
    land_walks,
    new_walk_rows,
    walk_of,
    walk_queue_in_lanes,
)
from voxfield.kernels.packet_traversal import PACKET_RAYS, new_packet_scratch, trace_packet
from voxfield.kernels.rising_lanes import (
    lanes_walk_rising,
    new_rising_walks,
    walk_rising_in_lanes,
)
from voxfield.kernels.scheduling import claim_items, new_run_queue
from voxfield.kernels.surface_approach import (
    FROM_SURFACE,
    settle_walk,
    trace_over_columns,
    walk_plan,
)
from voxfield.kernels.traversal import new_scratch, occluded, trace_ray
from voxfield.kernels.upward_rays import BLOCKED, UNDECIDED, rising_ray_query

#: Rays a thread claims at a time.
RAY_RUN = 256


@njit(parallel=True, cache=True, nogil=True)
def trace_rays(
    origins: np.ndarray, directions: np.ndarray, tmin: float, tmax: float,
    inner_nodes: np.ndarray, depth: int, stop_level: int,
    out_node: np.ndarray, out_level: np.ndarray, out_t: np.ndarray,
    out_normal: np.ndarray, out_steps: np.ndarray, columns=None, threads: int = 1,
) -> None:
    """Trace arbitrary rays at a fixed stop level (batch API, tests, oracles, probes) on
    ``threads`` workers. With a column-top pyramid (``svo.column_tops``) each ray crosses
    the air in it first (``kernels.surface_approach``, from the finest level, as rays from
    the surface do): the same hits; the steps count its cells. At LOD 0 those walks go
    side by side in SIMD lanes where that pays (``walks_in_lanes``)."""
    queue = new_run_queue()
    for _ in prange(threads):
        trace_ray_claims(origins, directions, tmin, tmax, inner_nodes, depth, stop_level,
                         out_node, out_level, out_t, out_normal, out_steps, columns, queue)


@njit(cache=True, nogil=True)
def trace_ray_claims(
    origins: np.ndarray, directions: np.ndarray, tmin: float, tmax: float,
    inner_nodes: np.ndarray, depth: int, stop_level: int,
    out_node: np.ndarray, out_level: np.ndarray, out_t: np.ndarray,
    out_normal: np.ndarray, out_steps: np.ndarray, columns, queue: np.ndarray,
) -> None:
    """One worker of ``trace_rays``: runs claimed from ``queue`` until none is left."""
    scratch = new_scratch(depth)
    walks = new_walk_queue()
    in_lanes = False
    if columns is not None:
        in_lanes = walks_in_lanes(tmin, depth, stop_level, columns)
    while True:
        first, last = claim_items(queue, origins.shape[0], RAY_RUN)
        if first == last:
            return
        if columns is not None and in_lanes:
            trace_run_in_lanes(origins, directions, first, last, tmin, tmax, inner_nodes,
                               depth, out_node, out_level, out_t, out_normal, out_steps,
                               scratch, columns, walks)
        else:
            trace_ray_chunk(origins, directions, first, last, tmin, tmax, inner_nodes, depth,
                            stop_level, out_node, out_level, out_t, out_normal, out_steps,
                            scratch, columns)


@njit(cache=True, nogil=True)
def new_walk_queue():
    """``trace_run_in_lanes``'s rows for a run: the rays (origin, direction, ``tmin``) and
    their walks (``lane_walk.new_walk_rows``)."""
    return new_walk_rows(RAY_RUN)


@njit(cache=True, nogil=True, inline="always")
def walks_in_lanes(tmin: float, depth: int, stop_level: int, columns) -> bool:
    """Whether ``trace_rays`` walks its runs in SIMD lanes (``kernels.lane_walk``): voxels
    (LOD 0), a pyramid with cell records, and a target where the lanes pay."""
    return (LANE_WALK_PAYS and columns.cell_records.shape[0] > 0
            and walk_plan(tmin, depth, stop_level, columns, FROM_SURFACE)[0] == 0)


@borrowing
def trace_run_in_lanes(
    origins: np.ndarray, directions: np.ndarray, first: int, last: int,
    tmin: float, tmax: float, inner_nodes: np.ndarray, depth: int,
    out_node: np.ndarray, out_level: np.ndarray, out_t: np.ndarray,
    out_normal: np.ndarray, out_steps: np.ndarray, scratch, columns, walks,
) -> None:
    """``trace_ray_chunk`` at LOD 0 over the pyramid with the walks in SIMD lanes
    (``lane_walk.walk_queue_in_lanes``), then each ray settled: the same answers. Secondary
    rays from voxel tops on the 2048² mountain terrain (a million, one thread) took 0.59-0.62×
    the one-ray walk's time, the walks alone 0.25-0.29×: incoherent rays mispredict the
    one-ray walk's branches most. ``walks``: ``new_walk_queue()``."""
    rays, walk_ints, walk_times = walks
    count = last - first
    copy_rays(origins, directions, first, count, rays, tmin)
    walk_queue_in_lanes(rays, count, depth, columns, walk_ints, walk_times, FROM_SURFACE, tmax)
    land_walks(rays, count, walk_ints, walk_times, columns, tmax, 0)
    for j in range(count):
        node, level, t, normal, steps = settle_walk(
            rays[j, 0], rays[j, 1], rays[j, 2], rays[j, 3], rays[j, 4], rays[j, 5], tmin, tmax,
            inner_nodes, depth, depth, scratch, columns, walk_of(walk_ints, walk_times, j))
        k = first + j
        out_node[k] = node
        out_level[k] = level
        out_t[k] = t
        out_normal[k] = normal
        out_steps[k] = steps


@borrowing
def trace_ray_chunk(
    origins: np.ndarray, directions: np.ndarray, first: int, last: int,
    tmin: float, tmax: float, inner_nodes: np.ndarray, depth: int, stop_level: int,
    out_node: np.ndarray, out_level: np.ndarray, out_t: np.ndarray,
    out_normal: np.ndarray, out_steps: np.ndarray, scratch, columns=None,
) -> None:
    """Rays ``first..last-1`` of ``trace_rays`` (``scratch``: ``traversal.new_scratch``)."""
    for k in range(first, last):
        if columns is None:
            node, level, t, normal, steps = trace_ray(
                origins[k, 0], origins[k, 1], origins[k, 2],
                directions[k, 0], directions[k, 1], directions[k, 2], tmin, tmax,
                inner_nodes, depth, stop_level, 0.0, 0.0, scratch,
            )
        else:
            node, level, t, normal, steps = trace_over_columns(
                origins[k, 0], origins[k, 1], origins[k, 2],
                directions[k, 0], directions[k, 1], directions[k, 2], tmin, tmax,
                inner_nodes, depth, stop_level, scratch, columns, FROM_SURFACE,
            )
        out_node[k] = node
        out_level[k] = level
        out_t[k] = t
        out_normal[k] = normal
        out_steps[k] = steps


@njit(parallel=True, cache=True, nogil=True)
def trace_rays_in_packets(
    origins: np.ndarray, directions: np.ndarray, tmin: float, tmax: float,
    inner_nodes: np.ndarray, depth: int, stop_level: int,
    out_node: np.ndarray, out_level: np.ndarray, out_t: np.ndarray,
    out_normal: np.ndarray, out_steps: np.ndarray, threads: int = 1,
) -> None:
    """``trace_rays`` through ``kernels.packet_traversal``: every 64 consecutive rays form
    one packet (the same results; faster where neighbours in the list are coherent)."""
    queue = new_run_queue()
    for _ in prange(threads):
        trace_packet_claims(origins, directions, tmin, tmax, inner_nodes, depth, stop_level,
                            out_node, out_level, out_t, out_normal, out_steps, queue)


@njit(cache=True, nogil=True)
def trace_packet_claims(
    origins: np.ndarray, directions: np.ndarray, tmin: float, tmax: float,
    inner_nodes: np.ndarray, depth: int, stop_level: int,
    out_node: np.ndarray, out_level: np.ndarray, out_t: np.ndarray,
    out_normal: np.ndarray, out_steps: np.ndarray, queue: np.ndarray,
) -> None:
    """One worker of ``trace_rays_in_packets``: runs of ``RAY_RUN`` rays (whole packets)
    claimed from ``queue`` until none is left."""
    n = origins.shape[0]
    scratch = new_packet_scratch(depth)
    tmins = np.full(PACKET_RAYS, tmin)
    tmaxs = np.full(PACKET_RAYS, tmax)
    while True:
        run_first, run_last = claim_items(queue, n, RAY_RUN)
        if run_first == run_last:
            return
        for first in range(run_first, run_last, PACKET_RAYS):
            last = min(run_last, first + PACKET_RAYS)
            rays = slice(first, last)
            trace_packet(last - first, origins[rays], directions[rays], tmins, tmaxs,
                         inner_nodes, depth, stop_level, scratch, out_node[rays],
                         out_level[rays], out_t[rays], out_normal[rays], out_steps[rays])


@njit(parallel=True, cache=True, nogil=True)
def occlude_rays(
    origins: np.ndarray, directions: np.ndarray, tmin: float, tmax: float,
    inner_nodes: np.ndarray, depth: int, columns, out_blocked: np.ndarray,
    out_steps: np.ndarray, threads: int = 1,
) -> None:
    """Any-hit queries at LOD 0 on ``threads`` workers: is ``[tmin, tmax)`` of each ray
    blocked by a voxel? With ``tmin`` 0, rising rays walk ``columns``
    (``kernels.upward_rays``; an empty pyramid sends every ray to the octree) before the
    octree."""
    queue = new_run_queue()
    for _ in prange(threads):
        occlude_ray_claims(origins, directions, tmin, tmax, inner_nodes, depth, columns,
                           out_blocked, out_steps, queue)


@njit(cache=True, nogil=True)
def occlude_ray_claims(
    origins: np.ndarray, directions: np.ndarray, tmin: float, tmax: float,
    inner_nodes: np.ndarray, depth: int, columns, out_blocked: np.ndarray,
    out_steps: np.ndarray, queue: np.ndarray,
) -> None:
    """One worker of ``occlude_rays``: runs claimed from ``queue`` until none is left, their
    pyramid walks in SIMD lanes where those pay (``rising_lanes.lanes_walk_rising``)."""
    scratch = new_scratch(depth)
    in_lanes = tmin == 0.0 and lanes_walk_rising(columns)
    walks = new_rising_walks(RAY_RUN if in_lanes else 0)
    while True:
        first, last = claim_items(queue, origins.shape[0], RAY_RUN)
        if first == last:
            return
        if in_lanes:
            occlude_run_in_lanes(origins, directions, first, last, tmax, inner_nodes, depth,
                                 columns, out_blocked, out_steps, scratch, walks)
        else:
            occlude_ray_chunk(origins, directions, first, last, tmin, tmax, inner_nodes,
                              depth, columns, out_blocked, out_steps, scratch)


@njit(cache=True, nogil=True, inline="always")
def copy_rays(origins: np.ndarray, directions: np.ndarray, first: int, count: int,
              rays: np.ndarray, bound: float) -> None:
    """Rays ``first..first+count-1`` into the rows of a lane queue: origin, direction and
    the walk's one bound (``tmin`` for ``walk_queue_in_lanes``, ``tmax`` for
    ``walk_rising_in_lanes``) in column 6."""
    for j in range(count):
        k = first + j
        for axis in range(3):
            rays[j, axis] = origins[k, axis]
            rays[j, 3 + axis] = directions[k, axis]
        rays[j, 6] = bound


@borrowing
def occlude_run_in_lanes(
    origins: np.ndarray, directions: np.ndarray, first: int, last: int, tmax: float,
    inner_nodes: np.ndarray, depth: int, columns, out_blocked: np.ndarray,
    out_steps: np.ndarray, scratch, walks,
) -> None:
    """``occlude_ray_chunk`` from ``tmin`` 0 with the rising rays' walks in SIMD lanes
    (``rising_lanes.walk_rising_in_lanes``), then the octree for those left undecided: the
    same answers and steps. Rays that do not rise are undecided at once, as there.
    ``walks``: ``new_rising_walks(RAY_RUN)``."""
    rays, verdicts, times, walk_steps = walks
    count = last - first
    copy_rays(origins, directions, first, count, rays, tmax)
    walk_rising_in_lanes(rays, count, columns, verdicts, times, walk_steps)
    for j in range(count):
        k = first + j
        if verdicts[j] != UNDECIDED:
            out_blocked[k] = verdicts[j] == BLOCKED
            out_steps[k] = walk_steps[j]
            continue
        blocked, steps = occluded(
            origins[k, 0], origins[k, 1], origins[k, 2],
            directions[k, 0], directions[k, 1], directions[k, 2], times[j], tmax,
            inner_nodes, depth, scratch,
        )
        out_blocked[k] = blocked
        out_steps[k] = walk_steps[j] + steps


@borrowing
def occlude_ray_chunk(
    origins: np.ndarray, directions: np.ndarray, first: int, last: int,
    tmin: float, tmax: float, inner_nodes: np.ndarray, depth: int, columns,
    out_blocked: np.ndarray, out_steps: np.ndarray, scratch,
) -> None:
    """Rays ``first..last-1`` of ``occlude_rays`` (``scratch``: ``traversal.new_scratch``)."""
    for k in range(first, last):
        verdict, start, cells = UNDECIDED, tmin, 0
        if tmin == 0.0:
            verdict, start, cells = rising_ray_query(
                origins[k, 0], origins[k, 1], origins[k, 2],
                directions[k, 0], directions[k, 1], directions[k, 2], tmax, columns,
            )
        if verdict != UNDECIDED:
            out_blocked[k] = verdict == BLOCKED
            out_steps[k] = cells
            continue
        blocked, steps = occluded(
            origins[k, 0], origins[k, 1], origins[k, 2],
            directions[k, 0], directions[k, 1], directions[k, 2], start, tmax,
            inner_nodes, depth, scratch,
        )
        out_blocked[k] = blocked
        out_steps[k] = cells + steps
