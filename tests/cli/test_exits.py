"""``cli.exits.report_failures``: how the command and the benchmark scripts end when
something goes wrong (one line and a status, never a traceback)."""

import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest

from voxfield.cli.exits import EXIT_INTERRUPTED, EXIT_USAGE, report_failures
from voxfield.errors import VoxfieldError

BENCHMARKS = Path(__file__).parents[2] / "benchmarks"


def _raise(exc):
    def command():
        raise exc
    return command


def test_a_status_passes_through_and_none_is_success():
    assert report_failures("x", lambda: 3) == 3
    assert report_failures("x", lambda: None) == 0


@pytest.mark.parametrize(("exc", "status", "line"), [
    (VoxfieldError("footprint must be between 2 and 16384"), EXIT_USAGE,
     "x: error: footprint must be between 2 and 16384"),
    (PermissionError(errno.EACCES, "Permission denied", "/out/a.png"), EXIT_USAGE,
     "x: error: cannot use /out/a.png: permission denied"),
    (KeyboardInterrupt(), EXIT_INTERRUPTED, "x: interrupted"),
])
def test_failures_are_one_line_and_a_status(exc, status, line, capsys):
    assert report_failures("x", _raise(exc)) == status
    assert capsys.readouterr().err.splitlines() == [line]


def test_a_programming_error_is_not_hidden():
    with pytest.raises(ZeroDivisionError):
        report_failures("x", lambda: 1 // 0)


@pytest.mark.parametrize(("script", "argv", "message"), [
    ("bench_traversal.py", ["--repeats", "0"], "argument --repeats: expected 1 or more"),
    ("bench_traversal.py", ["--footprint", "1"], "argument --footprint: expected 2 or more"),
    ("bench_traversal.py", ["--spp-side", "17"], "argument --spp-side: expected at most 16"),
    ("bench_gpu.py", ["--threads", "0"], "argument --threads: expected 1 or more"),
    ("bench_build.py", ["--fill", "0"], "argument --fill: expected 1 or more"),
    ("bench_error_table.py", ["--directions", "1"], "argument --directions: expected 2 or more"),
])
def test_benchmarks_refuse_impossible_options(script, argv, message):
    """Option errors carry the same program name as the errors found later (below)."""
    proc = subprocess.run([sys.executable, str(BENCHMARKS / script), *argv],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == EXIT_USAGE
    assert "Traceback" not in proc.stderr
    name = script.removesuffix(".py")
    assert proc.stderr.splitlines()[-1] == f"{name}: error: {message}, got '{argv[-1]}'"


def test_a_benchmark_reports_bad_input_found_late_in_one_line():
    """An unknown recipe is found when the scene is built, past argument parsing."""
    proc = subprocess.run(
        [sys.executable, str(BENCHMARKS / "bench_start_bounds.py"), "--recipe", "nowhere"],
        capture_output=True, text=True, timeout=300)
    assert proc.returncode == EXIT_USAGE
    assert len(proc.stderr.splitlines()) == 1
    assert proc.stderr.startswith("bench_start_bounds: error: unknown terrain recipe 'nowhere'")


def test_a_big_world_too_small_for_its_recipe_is_refused_first(shared_data):
    """``bench_traversal.py --big N`` builds its world before the long runs: a footprint with
    no room for the recipe's terrain ends the script at once, before any scene is built."""
    proc = subprocess.run(
        [sys.executable, str(BENCHMARKS / "bench_traversal.py"), "--no-peer", "--big", "3",
         "--footprint", "64"],
        capture_output=True, text=True, timeout=600)
    assert proc.returncode == EXIT_USAGE
    assert "Traceback" not in proc.stderr
    assert proc.stderr.splitlines()[-1].startswith(
        "bench_traversal: error: footprint 3 is too small for this terrain")
    assert "building mountain at 64²" not in proc.stderr


def _voxfield_writing_to(stdout, *argv):
    return subprocess.run([sys.executable, "-m", "voxfield", *argv], stdout=stdout,
                          stderr=subprocess.PIPE, text=True, timeout=300)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full (Linux)")
@pytest.mark.parametrize("argv", [["--help"], ["render", "--help"], [], ["scenes"]])
def test_output_to_a_full_disk_is_one_line_and_a_failure(argv):
    """argparse drops a failed write of its help (status 0, nothing written); a command's
    own output failed in its first write, named as "a file"."""
    with open("/dev/full", "w") as full:
        proc = _voxfield_writing_to(full, *argv)
    assert proc.returncode == EXIT_USAGE
    assert proc.stderr.splitlines() == [
        "voxfield: error: cannot write to standard output: the disk is full"]


@pytest.mark.parametrize("argv", [["--help"], ["scenes"]])
def test_output_to_a_closed_pipe_is_one_line_and_a_failure(argv):
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        proc = _voxfield_writing_to(write_end, *argv)
    finally:
        os.close(write_end)
    assert proc.returncode == EXIT_USAGE
    assert proc.stderr.splitlines() == ["voxfield: error: output closed early (broken pipe)"]
