"""Progress on stderr: bars only on a terminal, and the notice while kernels compile, said
once, only when something compiles."""

from __future__ import annotations

import io

from numba import njit

from voxfield.progress import COMPILING, compile_notice, progress_bar


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _bar_output(monkeypatch, stream, *, enabled: bool = True) -> str:
    monkeypatch.setattr("sys.stderr", stream)
    with progress_bar(total=3, desc="baking", enabled=enabled) as bar:
        for _ in range(3):
            bar.update(1)
    return stream.getvalue()


def test_a_bar_draws_on_a_terminal_only(monkeypatch):
    assert "baking" in _bar_output(monkeypatch, _Terminal())
    assert _bar_output(monkeypatch, io.StringIO()) == ""  # a log or a pipe
    assert _bar_output(monkeypatch, _Terminal(), enabled=False) == ""  # --quiet


def test_a_first_compile_is_announced_once_and_a_compiled_kernel_not_at_all():
    # New functions, so Numba compiles them here whatever other tests have compiled.
    def plus_one(x):
        return x + 1

    def twice(x):
        return 2 * x

    first, second = njit(plus_one), njit(twice)
    stream = io.StringIO()
    with compile_notice(stream=stream):
        assert first(1) == 2
        assert second(2) == 4
    assert stream.getvalue().splitlines() == [COMPILING]

    again = io.StringIO()
    with compile_notice(stream=again):
        assert first(3) == 4  # compiled already: nothing to say
    assert again.getvalue() == ""


def test_a_disabled_notice_says_nothing():
    def minus_one(x):
        return x - 1

    stream = io.StringIO()
    with compile_notice(enabled=False, stream=stream):
        assert njit(minus_one)(1) == 0
    assert stream.getvalue() == ""
