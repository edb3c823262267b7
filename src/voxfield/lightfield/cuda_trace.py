"""The light-field trace on a CUDA GPU: the probe maps go to the GPU once per probe set
(``PackedProbes.derived``) and every ray runs ``kernels.cuda_probe``'s thread, the CPU's own
per-ray code, so the answers equal ``trace_light_field``'s on the CPU."""

from __future__ import annotations

import numpy as np

from voxfield.kernels import cuda_probe
from voxfield.kernels.cuda_primary import launch_shape
from voxfield.kernels.probe_multi import LightFieldOutputs, ProbeField, hit_tolerance
from voxfield.lightfield.packed import PackedProbes

#: The maps a trace reads and the grid, in the kernel's argument order (``ProbeField``'s, with
#: the map resolution between them), and its outputs (``LightFieldOutputs``' order).
_MAPS = ProbeField._fields[:ProbeField._fields.index("resolution")]
_GRID = ProbeField._fields[ProbeField._fields.index("resolution") + 1:]
_OUTPUTS = LightFieldOutputs._fields


def kernel_arguments(packed: PackedProbes, modes: tuple, rays: tuple, out, maps=None,
                     to_device=np.ascontiguousarray) -> tuple:
    """``kernels.cuda_probe``'s arguments: ``modes`` (marcher, epsilon, ordering, fallback,
    params as the CPU kernel takes them), ``rays`` (origins, directions, tmin, tmax), the
    ``out`` (``LightFieldHits``) buffers, each array through ``to_device``; ``maps`` are the
    probe maps already there."""
    if maps is None:
        maps = tuple(to_device(np.ascontiguousarray(getattr(packed, n))) for n in _MAPS)
    marcher, eps_mode, ordering, fallback, params = modes
    return (marcher, eps_mode, ordering, fallback, to_device(params), *maps,
            packed.resolution, *(to_device(getattr(packed, n)) for n in _GRID),
            *(to_device(np.ascontiguousarray(a)) for a in rays), hit_tolerance(params),
            *(to_device(getattr(out, n)) for n in _OUTPUTS))


def trace_light_field_cuda(packed: PackedProbes, modes: tuple, origins: np.ndarray,
                           dirs: np.ndarray, tmin: np.ndarray, tmax: np.ndarray, out) -> None:
    """``lightfield.trace.trace_light_field``'s rays on the GPU into ``out``."""
    # optional: the CUDA target loads only when a GPU trace is asked for
    from numba import cuda

    maps = packed.derived("cuda", lambda: tuple(
        cuda.to_device(np.ascontiguousarray(getattr(packed, n))) for n in _MAPS))
    arguments = kernel_arguments(packed, modes, (origins, dirs, tmin, tmax), out, maps,
                                 cuda.to_device)
    blocks, threads = launch_shape(len(origins))
    cuda_probe.probe_kernel()[blocks, threads](*arguments)
    cuda.synchronize()
    for name, device_array in zip(_OUTPUTS, arguments[-len(_OUTPUTS):], strict=True):
        getattr(out, name)[...] = device_array.copy_to_host()
