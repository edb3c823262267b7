"""Any value for any option of the commands people script: the run finishes (status 0) or
ends in one clean line (status 2: the parser's usage error or ``voxfield: error:``), never
a traceback, whatever the value."""

from __future__ import annotations

import contextlib
import io

import pytest
from hypothesis import given
from hypothesis import strategies as st

from voxfield.cli import main

#: Values a script or a typo produces: empty, signed zero, NaN and infinities, overflow,
#: underflow, wrong separators, lists of the wrong length, non-ASCII digits, words.
HOSTILE = [
    "", " ", "0", "-0", "1", "2", "3", "-1", "-3", "0.5", "-0.5", "nan", "-nan", "inf",
    "-inf", "1e309", "1e300", "1e39", "-1e39", "1e-320", "1e30", "-1e30",
    "99999999999999999999", "0x10", "1_000",
    "abc", "1,2", "1,2,3", "1,2,3,4", "nan,1,2", "inf,0,0", "0,0,0", "4,4,4", "-4,4,-4",
    "1e30,0,0", "2x2x2", "0x2x2", "1x1x-1", "cone", "top", "oblique", "orbit", "\u0661",
    "\uff13", "\u00bd", ",", "--", "=",
]
values = st.one_of(
    st.sampled_from(HOSTILE),
    st.integers(-5, 40).map(str),
    st.floats(allow_nan=True, allow_infinity=True, width=32).map(repr),
    st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\0"),
            max_size=6),
)

RENDER_OPTIONS = [
    "--seed", "--fov", "--size", "--eye", "--target", "--camera", "--spp-side", "--lod",
    "--cone-scale", "--threshold", "--decay", "--base-lod", "--refinements", "--encoding",
    "--bright-ratio", "--colour-term", "--colour-variance", "--iterations",
    "--variance-normalisation", "--channel", "--threads", "--renderer", "--lod-colour",
    "--colour-storage", "--mesh-resolution", "--footprint", "--vertical-scale",
]
RENDERERS = ["reference", "lod", "error-aware", "adaptive"]


def run_cli(argv: list[str]) -> tuple[int, str]:
    """Status and stderr of one in-process run; any exception but SystemExit escapes."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 2
    return code, err.getvalue()


def assert_clean(code: int, err: str) -> None:
    assert "Traceback" not in err, err
    # NumPy's floating-point warnings ("overflow encountered in cast") reaching the user
    # mean a value went through arithmetic its checks should have stopped.
    assert "encountered in" not in err, err
    if code != 0:
        assert code == 2, (code, err)
        last = err.strip().splitlines()[-1]
        assert "error:" in last, err


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("cli_fuzz")


@given(renderer=st.sampled_from(RENDERERS),
       settings=st.lists(st.tuples(st.sampled_from(RENDER_OPTIONS), values),
                         min_size=1, max_size=2))
def test_render_with_any_option_values(out_dir, renderer, settings):
    argv = ["render", "builtin:sphere", "--quiet", "--renderer", renderer,
            "--out", str(out_dir / "fuzz.png")]
    if not any(name == "--size" for name, _ in settings):
        argv += ["--size", "8"]
    for name, value in settings:
        argv.append(f"{name}={value}")
    # A valid but large size is not what this test is about: cap what the values may ask.
    for name, value in settings:
        if name == "--size" and value.strip().isdecimal() and int(value) > 64:
            return
    assert_clean(*run_cli(argv))


BAKE_OPTIONS = ["--grid", "--resolution", "--renderer", "--samples", "--lod", "--cone-scale",
                "--threshold", "--decay", "--channel", "--scheduler", "--seed"]


@given(settings=st.lists(st.tuples(st.sampled_from(BAKE_OPTIONS), values),
                         min_size=1, max_size=2))
def test_bake_with_any_option_values(out_dir, settings):
    argv = ["bake", "builtin:sphere", "--quiet", "--fresh", "--out", str(out_dir / "probes")]
    named = {name for name, _ in settings}
    if "--grid" not in named:
        argv += ["--grid", "2x1x1"]
    if "--resolution" not in named:
        argv += ["--resolution", "8"]
    for name, value in settings:
        if name in ("--resolution", "--samples") and value.strip().isdecimal() and int(value) > 32:
            return
        if name == "--grid" and value.count("x") == 2 and value.replace("x", "").isdigit():
            return  # a well-formed grid may be large; its bounds have their own tests
        if name == "--scheduler" and ":" in value:
            value = "nowhere"  # an address would wait for its connection timeout
        argv.append(f"{name}={value}")
    assert_clean(*run_cli(argv))


@pytest.fixture(scope="module")
def probe_folder(out_dir):
    folder = out_dir / "baked"
    code, err = run_cli(["bake", "builtin:cornell", "--quiet", "--grid", "2x2x2",
                         "--resolution", "8", "--out", str(folder)])
    assert code == 0, err
    return folder


PROBE_RENDER_OPTIONS = [
    "--method", "--marcher", "--ordering", "--epsilon", "--epsilon-value", "--epsilon-k",
    "--step", "--colour-filter", "--filter", "--box-min", "--box-max", "--camera", "--eye",
    "--target", "--fov", "--size", "--threads",
]


@given(settings=st.lists(st.tuples(st.sampled_from(PROBE_RENDER_OPTIONS), values),
                         min_size=1, max_size=2))
def test_probe_render_with_any_option_values(out_dir, probe_folder, settings):
    argv = ["probe-render", str(probe_folder), "--quiet", "--out", str(out_dir / "view.png")]
    if not any(name == "--size" for name, _ in settings):
        argv += ["--size", "8"]
    for name, value in settings:
        if name == "--size" and value.strip().isdecimal() and int(value) > 64:
            return
        argv.append(f"{name}={value}")
    assert_clean(*run_cli(argv))
