"""One writer per output folder (``voxfield.folder_lock``): a job another process is
writing into a folder is refused before it reads or changes anything there; the same
process may claim a folder twice; a claim ends with its job, however the job ends."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import pytest

from cli_output import one_error_line
from voxfield import cli
from voxfield.folder_lock import LOCK_NAME, FolderBusyError, FolderLock
from voxfield.studies.report import StudyFolder

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="folder locks need fcntl")

HOLD = textwrap.dedent("""
    import sys
    from voxfield.folder_lock import FolderLock
    lock = FolderLock(sys.argv[1], "probe bake")
    assert lock.take(make=True)
    print("held", flush=True)
    sys.stdin.read()
""")


@pytest.fixture
def held_elsewhere(tmp_path):
    """A second process holding ``tmp_path / "out"``; it lets go when its stdin closes."""
    folder = tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(folder)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    yield folder, holder
    if holder.poll() is None:
        holder.stdin.close()
        holder.wait(timeout=30)


def test_a_folder_another_process_holds_is_refused_naming_the_job(held_elsewhere):
    folder, holder = held_elsewhere
    with pytest.raises(FolderBusyError) as refused:
        FolderLock(folder, "voxfield sweep").take()
    message = str(refused.value)
    assert str(folder) in message and "another voxfield job" in message
    assert f"probe bake, process {holder.pid}, since " in message


def test_the_claim_ends_with_the_holder_even_when_it_is_killed(held_elsewhere):
    folder, holder = held_elsewhere
    holder.send_signal(signal.SIGKILL)
    holder.wait(timeout=30)
    lock = FolderLock(folder, "voxfield sweep")
    assert lock.take()  # the system dropped the dead process's lock; its file is reused
    lock.release()
    assert not (folder / LOCK_NAME).exists()


def test_the_same_process_may_claim_a_folder_twice_and_the_file_goes_with_the_last(tmp_path):
    first, second = FolderLock(tmp_path, "a"), FolderLock(tmp_path, "b")
    assert first.take() and second.take()
    assert (tmp_path / LOCK_NAME).read_text().split()[0] == str(os.getpid())
    first.release()
    assert (tmp_path / LOCK_NAME).exists()  # the second claim still holds it
    second.release()
    assert not (tmp_path / LOCK_NAME).exists()
    second.release()  # giving up twice changes nothing


def test_a_folder_that_does_not_exist_is_claimed_only_when_made(tmp_path):
    lock = FolderLock(tmp_path / "new" / "deep", "voxfield compare")
    assert not lock.take() and not (tmp_path / "new").exists()
    assert lock.take(make=True) and (tmp_path / "new" / "deep" / LOCK_NAME).exists()
    lock.release()


def test_a_bake_into_a_folder_another_bake_holds_changes_nothing_there(held_elsewhere):
    """The second bake used to read the first one's header, clear its probes with --fresh
    or overwrite its records, and one of the two then failed on a checksum."""
    from voxfield.probes.folder_bake import bake_to_folder
    from voxfield.probes.grid import ProbeGrid
    from voxfield.probes.probe_set import BakeOptions
    from voxfield.scene.builtin import builtin_scene
    from voxfield.svo.build import build_octree

    folder, _ = held_elsewhere
    (folder / "probes.json").write_text("{}")  # what the first bake has written so far
    octree = build_octree(builtin_scene("pillars"))
    grid = ProbeGrid.fit(*octree.voxel_bounds, (2, 1, 2))

    def never(*_args, **_kw):
        raise AssertionError("a refused bake baked a probe")

    for fresh in (False, True):
        with pytest.raises(FolderBusyError):
            bake_to_folder(octree, grid, BakeOptions(resolution=8), folder, fresh=fresh,
                           baker=never)
        assert sorted(p.name for p in folder.iterdir()) == [LOCK_NAME, "probes.json"]
        assert (folder / "probes.json").read_text() == "{}"


def test_a_study_in_a_folder_another_job_holds_is_refused_before_its_work(held_elsewhere):
    folder, _ = held_elsewhere
    with pytest.raises(FolderBusyError):
        StudyFolder(folder, study="sweep")


def test_a_study_claims_the_folder_it_makes_and_lets_it_go_when_done(tmp_path):
    study = StudyFolder(tmp_path / "s", study="sweep")
    assert not (tmp_path / "s").exists()  # nothing claimed before the first output
    study.write_text("results.md", "# a table\n")
    assert (tmp_path / "s" / LOCK_NAME).exists()
    other = subprocess.run([sys.executable, "-c", HOLD, str(tmp_path / "s")], input="",
                           capture_output=True, text=True, timeout=120)
    assert other.returncode != 0 and "FolderBusyError" in other.stderr  # another process
    del study
    assert not (tmp_path / "s" / LOCK_NAME).exists()


def test_the_command_line_says_so_in_one_line(held_elsewhere, capsys):
    folder, holder = held_elsewhere
    code = cli.main(["bake", "builtin:cornell", "--grid", "2x1x2", "--resolution", "8",
                     "--out", str(folder), "--quiet"])
    assert code == 2
    line = one_error_line(capsys)
    assert "is being written by another voxfield job" in line and str(holder.pid) in line
