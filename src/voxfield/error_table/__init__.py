"""Error tables (EA §3.1–3.2): the error of sampling a node instead of its children."""

from voxfield.error_table.table import (
    ErrorTable,
    ErrorTableError,
    build_error_table,
    fit_report,
    load_error_table,
    raycast_errors,
    save_error_table,
)

__all__ = [
    "ErrorTable",
    "ErrorTableError",
    "build_error_table",
    "fit_report",
    "load_error_table",
    "raycast_errors",
    "save_error_table",
]
