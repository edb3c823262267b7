"""JSON files and summaries other tools read: strictly valid JSON, whatever NumPy or a
metric hands over. JSON has no NaN or infinity (Python writes ``Infinity``, which most
readers refuse), so a PSNR of identical images, or a depth never found, is ``null``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np


def to_json(value, *, finite: bool = True):
    """A JSON-valid copy: NumPy scalars and arrays become Python, paths strings, and NaN or
    ±inf None; ``finite=False`` keeps them for a file voxfield alone reads back (a probe
    set's header: Python writes and reads ``Infinity``)."""
    if isinstance(value, dict):
        return {str(k): to_json(v, finite=finite) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_json(v, finite=finite) for v in value]
    if isinstance(value, np.ndarray):
        return to_json(value.tolist(), finite=finite)
    if isinstance(value, np.generic):
        value = value.item()
    if finite and isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value


def json_text(value, *, indent: int | None = 2) -> str:
    """``value`` as strictly valid JSON text (``to_json``), any other object as its text."""
    return json.dumps(to_json(value), indent=indent, allow_nan=False, default=str)
