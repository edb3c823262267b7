"""Renderers by name: one place that knows every renderer, its options and their defaults.

Each renderer declares a frozen options dataclass beside its implementation; the dataclass
owns the defaults and documents each field (``metadata["help"]``), and the render function
reads its keyword defaults from it. The command line, the probe bake and the studies build
renderers here, so a new renderer is one entry in ``RENDERERS``.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
from collections.abc import Callable
from dataclasses import dataclass

from voxfield.errors import VoxfieldError
from voxfield.render.adaptive import AdaptiveOptions, render_adaptive
from voxfield.render.camera import Camera
from voxfield.render.error_aware import ErrorAwareOptions, render_error_aware
from voxfield.render.primary import LodOptions, ReferenceOptions, render_lod, render_reference
from voxfield.render.result import RenderResult
from voxfield.svo.octree import Octree, check_octree

#: Keywords every renderer takes besides its options.
COMMON_KEYWORDS = ("seed", "channel", "threads", "progress")


@dataclass(frozen=True)
class RendererEntry:
    """A renderer: its name, one line on what it is, its options type and function."""

    name: str
    summary: str
    options_type: type
    function: Callable[..., RenderResult]

    def options(self, **values) -> object:
        """The options with ``values`` over the defaults; unknown names are an error."""
        known = {f.name for f in dataclasses.fields(self.options_type)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise VoxfieldError(f"the {self.name} renderer has no option "
                                f"{', '.join(unknown)}; it takes {', '.join(sorted(known))}")
        return self.options_type(**values)

    def render(self, octree: Octree, camera: Camera, options=None, **keywords) -> RenderResult:
        """Render with ``options`` (defaults when None); ``keywords`` are the common ones
        (seed, channel, threads, progress) and any the function takes besides (e.g. a table)."""
        options = self.options() if options is None else options
        if not isinstance(options, self.options_type):
            raise VoxfieldError(f"the {self.name} renderer takes {self.options_type.__name__}, "
                                f"got {type(options).__name__}")
        check_octree(octree, "render")
        if not isinstance(camera, Camera):
            raise VoxfieldError(f"render needs a voxfield Camera, got {type(camera).__name__}")
        unknown = sorted(set(keywords) - _keywords_of(self.function))
        if unknown:
            raise VoxfieldError(f"the {self.name} renderer takes no {', '.join(unknown)}")
        # Shallow: the fields are plain values, and asdict's deep copy cost a small render
        # 70 µs.
        fields = {f.name: getattr(options, f.name) for f in dataclasses.fields(options)}
        return self.function(octree, camera, **fields, **keywords)


@functools.cache
def _keywords_of(function: Callable) -> frozenset[str]:
    """The keywords a render function takes (once per function: a signature costs tens of
    microseconds, a small probe's render a few hundred)."""
    return frozenset(inspect.signature(function).parameters)


RENDERERS: dict[str, RendererEntry] = {
    entry.name: entry for entry in (
        RendererEntry("reference", "4×4 CMJ rays per pixel at LOD 0: the ground truth "
                      "(EA §5.1.1)", ReferenceOptions, render_reference),
        RendererEntry("lod", "one ray per pixel at a fixed LOD or the pixel cone's LOD "
                      "(EA §5.1.1)", LodOptions, render_lod),
        RendererEntry("error-aware", "one ray at the base LOD, refined 2×2 where the error "
                      "table says so (EA §5.1.3)", ErrorAwareOptions, render_error_aware),
        RendererEntry("adaptive", "one ray, refined where the luminance variance is high "
                      "(the variance baseline, EA §5.1.2)", AdaptiveOptions, render_adaptive),
    )
}


def renderer_entry(name: str) -> RendererEntry:
    """The registered renderer ``name``; an unknown name is a clear error."""
    try:
        return RENDERERS[name]
    except KeyError:
        raise VoxfieldError(f"unknown renderer {name!r}; choose one of "
                            f"{', '.join(RENDERERS)}") from None


def renderer_options(name: str, **values) -> object:
    """Options of renderer ``name``: its defaults with ``values`` over them."""
    return renderer_entry(name).options(**values)


def render(octree: Octree, camera: Camera, renderer: str = "reference", options=None,
           **keywords) -> RenderResult:
    """Render with the renderer named ``renderer``. Option fields may come as an options
    object or as keywords (``render(o, c, "error-aware", threshold=0.1, seed=3)``)."""
    entry = renderer_entry(renderer)
    fields = {f.name for f in dataclasses.fields(entry.options_type)}
    values = {k: keywords.pop(k) for k in list(keywords) if k in fields}
    if options is None:
        options = entry.options(**values)
    elif values:
        options = dataclasses.replace(options, **values)
    return entry.render(octree, camera, options, **keywords)
