"""Cameras, renderers and their results."""

from voxfield.render.adaptive import render_adaptive
from voxfield.render.camera import (
    Camera,
    cube_cameras,
    oblique_camera,
    orbit_camera,
    top_down_camera,
)
from voxfield.render.error_aware import render_error_aware
from voxfield.render.primary import render_lod, render_reference
from voxfield.render.registry import RENDERERS, render, renderer_options
from voxfield.render.result import RenderResult

__all__ = [
    "RENDERERS",
    "Camera",
    "RenderResult",
    "cube_cameras",
    "oblique_camera",
    "orbit_camera",
    "render",
    "render_adaptive",
    "render_error_aware",
    "render_lod",
    "render_reference",
    "renderer_options",
    "top_down_camera",
]
