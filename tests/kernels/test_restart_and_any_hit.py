"""Restarts below the root and any-hit queries give exactly what a plain traversal gives."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from kernels.test_traversal import adversarial_rays
from random_scenes import overhanging_terrain, random_scene
from voxfield.kernels.packet_traversal import PACKET_RAYS, new_packet_scratch, trace_packet
from voxfield.kernels.traversal import new_scratch, trace_ray
from voxfield.kernels.traversal import occluded as occluded_ray
from voxfield.render import orbit_camera
from voxfield.render.ray_query import occluded, trace
from voxfield.scene.builtin import pillars
from voxfield.svo import build_octree


@njit
def _one_by_one(o, d, inner, depth, stop, out, out_t):
    """Every ray with fresh scratch: no restart is possible."""
    for k in range(o.shape[0]):
        scratch = new_scratch(depth)
        node, level, t, normal, steps = trace_ray(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1],
                                                  d[k, 2], 0.0, math.inf, inner, depth, stop,
                                                  0.0, 0.0, scratch)
        out[k, 0] = node
        out[k, 1] = level
        out[k, 2] = normal
        out[k, 3] = steps
        out_t[k] = t


@njit
def _interleaved(o, d, tmins, inner, depth, stop, fresh, out, out_t):
    """Closest-hit and any-hit queries taking turns, with per-ray start times, on one shared
    scratch (``fresh``: a new scratch per query, so nothing restarts)."""
    scratch = new_scratch(depth)
    for k in range(o.shape[0]):
        if fresh:
            scratch = new_scratch(depth)
        if k % 3 == 2:
            blocked, steps = occluded_ray(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2],
                                          tmins[k], math.inf, inner, depth, scratch)
            out[k, 0] = 1 if blocked else 0
            out[k, 1] = 0
            out[k, 2] = 0
            out[k, 3] = steps
            out_t[k] = 0.0
            continue
        node, level, t, normal, steps = trace_ray(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1],
                                                  d[k, 2], tmins[k], math.inf, inner, depth,
                                                  stop, 0.0, 0.0, scratch)
        out[k, 0] = node
        out[k, 1] = level
        out[k, 2] = normal
        out[k, 3] = steps
        out_t[k] = t


def test_restarts_from_start_paths_match_fresh_rays_when_queries_interleave():
    """Coherent rays that start inside the scene (as beam-started primary rays do) restart
    from the last ray's start node; any-hit and closest-hit start paths stay apart."""
    for octree in _scenes():
        lo, hi = octree.voxel_bounds
        cam = orbit_camera(lo, hi, size=40)
        origins, directions = cam.rays(side=2, seed=3)
        centre = (np.asarray(lo) + np.asarray(hi)) / 2
        reach = np.linalg.norm(centre - origins, axis=1)
        rng = np.random.default_rng(4)
        tmins = reach * rng.choice([0.0, 0.6, 0.8, 0.9], size=len(reach))
        for lod in (0, 1):
            stop = octree.depth - lod
            got = np.empty((len(origins), 4), np.int64)
            got_t = np.empty(len(origins))
            want = np.empty_like(got)
            want_t = np.empty_like(got_t)
            _interleaved(origins, directions, tmins, octree.inner_nodes, octree.depth, stop,
                         False, got, got_t)
            _interleaved(origins, directions, tmins, octree.inner_nodes, octree.depth, stop,
                         True, want, want_t)
            assert np.array_equal(got, want)
            assert np.array_equal(got_t, want_t)


def _scenes():
    yield build_octree(pillars(32))
    yield build_octree(random_scene(4, n=2000, size=32))


def _rays_up_from_tops(octree, seed: int):
    """Shadow-style rays: from the middle of every voxel's top face, in random upward
    directions."""
    top = octree.node_coords(octree.depth) + [0.5, 1.0, 0.5]
    up = np.random.default_rng(seed).normal(size=top.shape)
    up[:, 1] = np.abs(up[:, 1])
    return top, up


def test_restarted_rays_match_rays_from_the_root_in_everything():
    for octree in _scenes():
        lo, hi = octree.voxel_bounds
        cam = orbit_camera(lo, hi, size=40)
        coherent = cam.rays(side=2, seed=1)
        for origins, directions in (coherent, adversarial_rays(lo, hi, 3000, seed=2)):
            for lod in (0, 2):
                stop = octree.depth - lod
                got = trace(octree, origins, directions, lod=lod)  # batches restart
                want = np.empty((len(origins), 4), np.int64)
                want_t = np.empty(len(origins))
                _one_by_one(origins, directions, octree.inner_nodes, octree.depth, stop, want,
                            want_t)
                assert np.array_equal(got.node, want[:, 0])
                assert np.array_equal(got.level[got.hit], want[got.hit, 1])
                assert np.array_equal(got.normal_code[got.hit], want[got.hit, 2])
                assert np.array_equal(got.steps, want[:, 3])
                assert np.array_equal(got.t, want_t)  # bit for bit


def test_any_hit_blocks_exactly_the_rays_that_hit_and_takes_fewer_steps():
    for solid_interiors, octree in zip((True, False), _scenes(), strict=True):
        lo, hi = octree.voxel_bounds
        origins, directions = adversarial_rays(lo, hi, 4000, seed=5)
        for tmax in (math.inf, 3.5):
            closest = trace(octree, origins, directions, tmax=tmax)
            anyhit = occluded(octree, origins, directions, tmax=tmax)
            assert np.array_equal(anyhit.blocked, closest.hit)
            assert np.all(anyhit.steps <= closest.steps)
        # Shadow-style rays from surface points: solid interiors stop them early.
        top, d = _rays_up_from_tops(octree, seed=0)
        closest = trace(octree, top, d)
        anyhit = occluded(octree, top, d)
        assert np.array_equal(anyhit.blocked, closest.hit)
        assert np.all(anyhit.steps <= closest.steps)
        if solid_interiors:  # pillars have solid 2³ and 4³ blocks: rays stop at them
            assert anyhit.steps.sum() < 0.9 * closest.steps.sum()


@njit
def _any_hit_packets(o, d, tmax, inner, depth, blocked, steps):
    """``occluded`` for every ray through any-hit packets of up to 64 rays."""
    scratch = new_packet_scratch(depth)
    n = o.shape[0]
    tmins = np.zeros(PACKET_RAYS)
    tmaxs = np.full(PACKET_RAYS, tmax)
    node = np.empty(PACKET_RAYS, np.int64)
    level = np.empty(PACKET_RAYS, np.int64)
    t = np.empty(PACKET_RAYS)
    normal = np.empty(PACKET_RAYS, np.int64)
    ray_steps = np.empty(PACKET_RAYS, np.int64)
    for first in range(0, n, PACKET_RAYS):
        count = min(PACKET_RAYS, n - first)
        trace_packet(count, o[first:first + count], d[first:first + count], tmins, tmaxs,
                     inner, depth, depth, scratch, node, level, t, normal, ray_steps, True)
        for k in range(count):
            blocked[first + k] = node[k] != -1
            steps[first + k] = ray_steps[k]


def test_any_hit_packets_equal_the_scalar_any_hit_query():
    """Packets stop in solid nodes where ``occluded`` stops: same verdict, same steps, for
    rays from voxel tops (the sun bake's shadow rays) and adversarial rays."""
    for octree in _scenes():
        lo, hi = octree.voxel_bounds
        origins, directions = adversarial_rays(lo, hi, 3000, seed=6)
        top, up = _rays_up_from_tops(octree, seed=1)
        for o, d in ((origins, directions), (top, up)):
            for tmax in (math.inf, 3.5):
                want = occluded(octree, o, d, tmax=tmax)
                blocked = np.empty(len(o), np.bool_)
                steps = np.empty(len(o), np.int64)
                _any_hit_packets(np.ascontiguousarray(o, np.float64),
                                 np.ascontiguousarray(d, np.float64), tmax,
                                 octree.inner_nodes, octree.depth, blocked, steps)
                assert np.array_equal(blocked, want.blocked)
                assert np.array_equal(steps, want.steps)
                assert want.blocked.any() and not want.blocked.all()


def test_any_hit_over_column_tops_keeps_every_verdict_in_fewer_steps():
    """``occluded(columns=True)``: rising rays walk the column-top pyramid first; every
    ray, rising or not, from any origin, with any ``tmin``, keeps its verdict (on small
    scenes the walk can cost a step or two more than the octree)."""
    for octree in (*_scenes(), build_octree(overhanging_terrain(seed=4, size=30))):
        lo, hi = octree.voxel_bounds
        origins, directions = adversarial_rays(lo, hi, 3000, seed=8)
        top, up = _rays_up_from_tops(octree, seed=2)
        for o, d in ((origins, directions), (top, up)):
            for tmin, tmax in ((0.0, math.inf), (0.0, 3.5), (0.25, math.inf)):
                plain = occluded(octree, o, d, tmin=tmin, tmax=tmax)
                walked = occluded(octree, o, d, tmin=tmin, tmax=tmax, columns=True)
                assert np.array_equal(walked.blocked, plain.blocked)
                if tmin > 0.0:  # only rays from tmin = 0 walk the columns
                    assert np.array_equal(walked.steps, plain.steps)
    # Over wide ground the pyramid skips what the octree walks node by node.
    octree = build_octree(overhanging_terrain(seed=5, size=120))
    top, up = _rays_up_from_tops(octree, seed=3)
    plain = occluded(octree, top, up)
    walked = occluded(octree, top, up, columns=True)
    assert np.array_equal(walked.blocked, plain.blocked)
    assert walked.blocked.any() and not walked.blocked.all()
    assert walked.steps.sum() < 0.8 * plain.steps.sum()
