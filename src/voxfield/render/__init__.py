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
from voxfield.render.renderers import render, render_lod, render_reference
from voxfield.render.result import RenderResult

__all__ = [
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
    "top_down_camera",
]
