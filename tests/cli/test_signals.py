"""Ctrl-C, termination signals and running out of memory end a command in one line, and
leave no temporary file behind."""

from __future__ import annotations

import importlib
import os
import signal

import pytest

from voxfield.atomic import atomic_path
from voxfield.cli import main
from voxfield.cli.exits import Terminated, stopping_on_termination


def _last_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_a_termination_signal_cleans_up_like_ctrl_c(tmp_path):
    before = signal.getsignal(signal.SIGTERM)
    target = tmp_path / "big.npz"
    with pytest.raises(Terminated), stopping_on_termination(), atomic_path(target) as tmp:
        tmp.write_bytes(b"half an octree")
        os.kill(os.getpid(), signal.SIGTERM)
    assert list(tmp_path.iterdir()) == []  # neither the target nor the hidden temporary
    assert signal.getsignal(signal.SIGTERM) == before  # the handler is put back


def test_a_signal_ignored_before_stays_ignored():
    # under nohup SIGHUP is ignored: a logout must not stop the command
    before = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        with stopping_on_termination():
            assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
            assert callable(signal.getsignal(signal.SIGTERM))
    finally:
        signal.signal(signal.SIGHUP, before)


@pytest.mark.parametrize("signum, status, words", [
    (signal.SIGTERM, 143, "terminated (SIGTERM)"), (signal.SIGHUP, 129, "terminated (SIGHUP)"),
    (signal.SIGINT, 130, "interrupted"),
])
def test_a_command_stopped_by_a_signal_says_so_in_one_line(signum, status, words, tmp_path,
                                                          monkeypatch, capsys):
    def stopped(args):
        with atomic_path(tmp_path / "x.png") as tmp:
            tmp.write_bytes(b"partial")
            os.kill(os.getpid(), signum)
        return 0

    monkeypatch.setattr("voxfield.cli.cmd_render.run", stopped)
    # a suite started under nohup inherits SIGHUP ignored, which the command rightly keeps
    before = signal.signal(signum, signal.SIG_DFL if signum != signal.SIGINT
                           else signal.default_int_handler)
    try:
        code = main(["render", "builtin:sphere", "--size", "8", "--out",
                     str(tmp_path / "x.png")])
    finally:
        signal.signal(signum, before)
    assert code == status
    assert _last_line(capsys) == f"voxfield: {words}"
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_while_the_command_loads_is_one_line(monkeypatch, capsys):
    # the parser imports the command's modules (numpy, Numba): a second in which Ctrl-C
    # printed the import machinery's traceback
    def loading(_command):
        raise KeyboardInterrupt

    monkeypatch.setattr(importlib.import_module("voxfield.cli.main"), "build_parser", loading)
    assert main(["render", "builtin:sphere"]) == 130
    assert _last_line(capsys) == "voxfield: interrupted"


def test_running_out_of_memory_is_one_line(monkeypatch, capsys):
    def greedy(args):
        raise MemoryError("Unable to allocate 2.00 GiB for an array")

    monkeypatch.setattr("voxfield.cli.cmd_render.run", greedy)
    assert main(["render", "builtin:sphere", "--out", "unused.png"]) == 2
    line = _last_line(capsys)
    assert line.startswith("voxfield: error: out of memory (Unable to allocate 2.00 GiB")


def test_ctrl_c_while_a_finished_command_exits_changes_nothing(tmp_path):
    """A Ctrl-C in the tenths of a second the interpreter takes to shut down after a command
    has finished killed the process without a word, status 130, over complete outputs; here
    it lands in an exit handler, as it would in the interpreter's own shutdown."""
    import subprocess
    import sys

    script = tmp_path / "finished_then_ctrl_c.py"
    script.write_text(
        "import atexit, importlib, os, signal, time\n"
        "cli = importlib.import_module('voxfield.cli.main')  # the module, not its main\n"
        "cli.main = lambda argv=None: 3  # a command that finished with status 3\n"
        "atexit.register(lambda: (os.kill(os.getpid(), signal.SIGINT), time.sleep(0.2)))\n"
        "cli.program()\n")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=120)
    assert (done.returncode, done.stderr) == (3, "")
