"""Issue #34: temporary files, leftovers and locks belong to this project alone."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.errors import OutputFileError
from dualpixel.io.atomic import PARTIAL_GLOB, atomic_path, remove_partials
from dualpixel.io.lock import folder_lock
from dualpixel.synthesis.scenes import SceneConfig, write_scene_folder


def test_cleanup_removes_only_this_projects_leftovers(tmp_path):
    users = [tmp_path / ".notes.partial.txt", tmp_path / "a" / ".x.partial.png",
             tmp_path / "a" / "draft.partial"]
    for path in users:
        path.parent.mkdir(exist_ok=True)
        path.write_text("the user's")
    with atomic_path(tmp_path / "a" / "frame.png") as tmp:
        tmp.write_bytes(b"half")
        assert list(tmp_path.rglob(PARTIAL_GLOB)) == [tmp]  # our temporary name, and only it
    leftover = tmp_path / "a" / ".frame.dualpixel-partial-k3j2.png"  # what a kill leaves
    leftover.write_bytes(b"half")
    assert remove_partials(tmp_path) == 1
    assert not leftover.exists()
    assert all(path.read_text() == "the user's" for path in users)


def test_scenes_holds_its_folder(tmp_path):
    out = tmp_path / "scenes"
    config = SceneConfig(frames=1, width=32, height=24)
    out.mkdir()  # (a folder the holder made and left empty goes with its lock)
    with folder_lock(out, "synth"):
        with pytest.raises(OutputFileError, match="being written by pid"):
            write_scene_folder(out, 1, config, progress=False)
        result = CliRunner().invoke(cli, ["scenes", "--output", str(out), "--sequences", "1",
                                          "--frames", "1", "--size", "32x24"])
        assert result.exit_code == 1 and "being written" in result.output, result.output
        assert not any(out.glob("seq_*"))
    (out / ".rgb.dualpixel-partial-1.png").write_bytes(b"half")  # a killed run's leftover
    write_scene_folder(out, 1, config, progress=False)
    assert (out / "seq_000" / "rgb" / "frame_0000.png").is_file()
    assert not list(out.rglob(PARTIAL_GLOB))


def test_file_errors_cross_process_boundaries_whole():
    """A worker process's error reaches the parent with its path and message (pickled), instead
    of failing to unpickle there (a broken pool, or a multiprocessing pool that hangs)."""
    import pickle

    from dualpixel.errors import InputFileError, OutputFileError

    for error in (InputFileError("a/b.png", "cannot be read"),
                  OutputFileError("out/c.npy", "no space left on device")):
        again = pickle.loads(pickle.dumps(error))
        assert type(again) is type(error)
        assert (again.path, again.problem, str(again)) == (error.path, error.problem, str(error))


def test_a_released_lock_leaves_no_holder_and_no_empty_folder(tmp_path, tiny_synthetic_dataset):
    """Issue #72 / #73: a finished folder's lock file no longer names its writer (so two runs'
    folders are byte-identical), and a run refused before writing leaves no folder behind."""
    made = tmp_path / "new" / "run"
    with folder_lock(made, "train") as lock:
        assert "pid" in lock.read_text()
    assert not (tmp_path / "new").exists()
    kept = tmp_path / "kept"
    with folder_lock(kept, "synth") as lock:
        (kept / "frame.png").write_bytes(b"data")
    assert lock.read_text() == "" and (kept / "frame.png").read_bytes() == b"data"
    existing = tmp_path / "existing"
    existing.mkdir()
    with folder_lock(existing, "synth"):
        pass
    assert existing.is_dir()  # the user's folder stays, with an empty lock
    result = CliRunner().invoke(cli, ["train", "--output", str(tmp_path / "refused"),
                                      "--set", f"synthetic_data={tiny_synthetic_dataset}",
                                      "--set", "synthetic_as_frames=true",
                                      "--set", "patch_size=4096"])
    assert result.exit_code != 0 and "patch_size 4096 exceeds" in result.output, result.output
    assert not (tmp_path / "refused").exists()
