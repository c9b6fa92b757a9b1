"""`synth` stopped (Ctrl-C, SIGTERM or SIGKILL, workers included) mid-run, then rerun, gives a
dataset byte-identical to an uninterrupted run, manifest and lock file included. Both use 2
workers (one torch thread each): a different thread count may round a pixel differently."""

import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from dualpixel.data import discover_dp_dataset
from dualpixel.errors import InputFileError
from dualpixel.synthesis.dataset import SynthConfig, synthesize_dataset
from dualpixel.synthesis.scenes import SceneConfig, write_scene_folder

CONFIG = {"lens_sets": ("set0", "set4"), "max_layers": 40, "seed": 3}

# The run stops itself (SIGSTOP) once its second manifest line is on disk, so the signal below
# lands mid-run however fast the workers return their frames (they may return them in a burst).
_CHILD = textwrap.dedent("""
    import os, signal, sys
    # Ctrl-C raises KeyboardInterrupt, as from a shell, even where the test process ignores it
    signal.signal(signal.SIGINT, signal.default_int_handler)
    from dualpixel.synthesis.dataset import SynthConfig, synthesize_dataset
    written, fsync = [0], os.fsync
    def pausing_fsync(fd):
        fsync(fd)
        if os.readlink(f"/proc/self/fd/{fd}").endswith("manifest.jsonl"):
            written[0] += 1
            if written[0] == 2:
                os.kill(os.getpid(), signal.SIGSTOP)
    os.fsync = pausing_fsync
    synthesize_dataset(sys.argv[1], "rgbd", sys.argv[2],
                       SynthConfig(lens_sets=("set0", "set4"), max_layers=40, seed=3),
                       workers=2, progress=False)
""")


def _stopped(pid: int) -> bool:
    """Whether process ``pid`` is stopped (state T in ``/proc/PID/stat``)."""
    stat = Path(f"/proc/{pid}/stat").read_text()
    return stat[stat.rindex(")") + 2] in "Tt"


def every_file(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("scenes")
    write_scene_folder(root, 4, SceneConfig(width=96, height=64, frames=3, leaves=8), seed=2,
                       progress=False)
    return root


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_killed_synth_resumes_byte_identical(scenes, tmp_path, stop):
    reference = tmp_path / "reference"
    synthesize_dataset(scenes, "rgbd", reference, SynthConfig(**CONFIG), workers=2,
                       progress=False)

    killed = tmp_path / "killed"
    child = subprocess.Popen(
        [sys.executable, "-c", _CHILD, str(scenes), str(killed)], start_new_session=True,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
    )
    manifest = killed / "manifest.jsonl"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and child.poll() is None:
        if _stopped(child.pid):
            assert manifest.read_text().count("\n") == 2
            os.killpg(child.pid, stop)  # the parent and its worker processes, as Ctrl-C does
            os.killpg(child.pid, signal.SIGCONT)  # a stopped process takes it on waking
            break
        time.sleep(0.01)
    assert child.wait(timeout=60) == -stop, "the run finished before it was stopped"
    assert json.loads((killed / "dataset.json").read_text())["status"] == "incomplete"
    with pytest.raises(InputFileError, match="unfinished"):
        discover_dp_dataset(killed, "train")
    # What a kill can leave besides: a temporary file, and one view of a frame whose other
    # files and manifest line were never written.
    first = json.loads(manifest.read_text().splitlines()[0])
    (killed / "train_c" / "source" / ".frame_0009.dualpixel-partial-x.png").write_bytes(b"junk")
    orphan = (killed / first["outputs"]["left"]).parent.parent / "seq_004" / "frame_0002.png"
    orphan.parent.mkdir(parents=True, exist_ok=True)
    orphan.write_bytes(b"not a finished view")

    summary = synthesize_dataset(scenes, "rgbd", killed, SynthConfig(**CONFIG), workers=2,
                                 progress=False)
    assert summary["status"] == "complete"
    assert every_file(killed) == every_file(reference)


def test_parallel_runs_write_identical_manifests(scenes, tmp_path):
    for name in ("a", "b"):
        synthesize_dataset(scenes, "rgbd", tmp_path / name, SynthConfig(**CONFIG), workers=2,
                           progress=False)
    assert every_file(tmp_path / "a") == every_file(tmp_path / "b")
    keys = [json.loads(line)["key"] for line in
            (tmp_path / "a" / "manifest.jsonl").read_text().splitlines()]
    assert keys == sorted(keys)  # plan order, not completion order


def test_a_run_that_finished_nothing_does_not_lock_its_folder(scenes, tmp_path):
    out = tmp_path / "d"
    synthesize_dataset(scenes, "rgbd", out, SynthConfig(**CONFIG), progress=False, limit=0)
    other = SynthConfig(**{**CONFIG, "seed": 4})
    assert synthesize_dataset(scenes, "rgbd", out, other, progress=False)["status"] == "complete"
    with pytest.raises(InputFileError, match="differs in seed"):
        synthesize_dataset(scenes, "rgbd", out, SynthConfig(**CONFIG), progress=False)


def test_three_shards_merged_equal_the_single_run(scenes, tmp_path):
    from click.testing import CliRunner

    from dualpixel.cli.main import cli

    synthesize_dataset(scenes, "rgbd", tmp_path / "single", SynthConfig(**CONFIG), workers=2,
                       progress=False)
    args = ["synth", "--input", str(scenes), "--settings", "paper", "--lens-sets", "set0,set4",
            "--layers", "40",
            "--seed", "3", "--workers", "2"]
    runner = CliRunner()
    for k in range(3):
        result = runner.invoke(cli, [*args, "--output", str(tmp_path / f"part{k}"), "--shard",
                                     f"{k}/3"])
        assert result.exit_code == 0, result.output
    parts = [str(tmp_path / f"part{k}") for k in (2, 0, 1)]  # any order
    incomplete = runner.invoke(cli, ["merge-shards", *parts[:2], "--output", str(tmp_path / "m")])
    assert incomplete.exit_code == 2 and "exactly once" in incomplete.output
    merged = runner.invoke(cli, ["merge-shards", *parts, "--output", str(tmp_path / "merged")])
    assert merged.exit_code == 0, merged.output
    assert every_file(tmp_path / "merged") == every_file(tmp_path / "single")
    bad = runner.invoke(cli, [*args, "--output", str(tmp_path / "x"), "--shard", "3/3"])
    assert bad.exit_code == 2 and "--shard" in bad.output


def test_paths_from_manifests_and_options_stay_inside_their_folders(scenes, tmp_path):
    """Issue #34: a shard's manifest naming an absolute path or ``../`` is refused before any
    file is written; a split name that is a path is refused."""
    from click.testing import CliRunner

    from dualpixel.cli.main import cli

    runner = CliRunner()
    args = ["synth", "--input", str(scenes), "--lens-sets", "set0", "--layers", "40", "--seed", "3"]
    parts = []
    for k in range(2):
        part = tmp_path / f"part{k}"
        done = runner.invoke(cli, [*args, "--output", str(part), "--shard", f"{k}/2"])
        assert done.exit_code == 0, done.output
        parts.append(part)
    manifest = parts[1] / "manifest.jsonl"
    original = manifest.read_text()
    victim = tmp_path / "victim.txt"
    victim.write_text("the user's file")
    for hostile in (str(victim), "../../victim.txt"):
        records = [json.loads(line) for line in original.splitlines()]
        records[0]["outputs"]["left"] = hostile
        manifest.write_text("".join(json.dumps(r) + "\n" for r in records))
        out = tmp_path / f"merged-{len(hostile)}"
        result = runner.invoke(cli, ["merge-shards", *map(str, parts), "--output", str(out)])
        assert result.exit_code == 1, result.output
        assert "manifest.jsonl" in result.output and "leads outside" in result.output
        assert victim.read_text() == "the user's file"
        assert not out.exists() or not any(out.rglob("*.png"))
    manifest.write_text(original)
    # a shard description that no `synth --shard` wrote: named, never a traceback
    good = [json.loads((part / "dataset.json").read_text()) for part in parts]
    for change, message in (({"shard": "x"}, "shard must be"), ({"shard": [2, 2]}, "shard must be"),
                            ({"version": None}, "version must be a string"),
                            ({"config": [1]}, "config must be a mapping"),
                            ({"config": {**good[0]["config"], "bogus": 1}},
                             "unknown synthesis setting.*bogus"),
                            ({"config": {**good[0]["config"], "seed": "x"}}, "seed must be")):
        for part, original_description in zip(parts, good):  # both, so they still agree
            (part / "dataset.json").write_text(json.dumps({**original_description, **change}))
        out = tmp_path / "merged-bad"
        result = runner.invoke(cli, ["merge-shards", *map(str, parts), "--output", str(out)])
        assert result.exit_code == 1 and "Traceback" not in result.output, result.output
        assert "dataset.json" in result.output and re.search(message, result.output), \
            result.output
        assert not out.exists()
    for split in ("../../x", "a/b", ".."):
        result = runner.invoke(cli, [*args, "--output", str(tmp_path / "s"), "--split", split])
        assert result.exit_code == 2 and "split must be a plain name" in result.output
    assert not (tmp_path / "x").exists()


_HOLDER = textwrap.dedent("""
    import sys, time
    from dualpixel.io.lock import folder_lock
    with folder_lock(sys.argv[1], "synth"):
        print("locked", flush=True)
        time.sleep(60)
""")


def test_two_writers_into_one_folder_one_is_refused(scenes, tmp_path):
    """Issue #34: a second `synth` into a folder another process writes gets an error naming
    the holder; once the holder is gone (SIGKILL included) its lock is taken over."""
    from click.testing import CliRunner

    from dualpixel.cli.main import cli

    out = tmp_path / "data"
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, str(out)], stdout=subprocess.PIPE,
                              text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        args = ["synth", "--input", str(scenes), "--output", str(out), "--lens-sets", "set0",
                "--layers", "40"]
        result = CliRunner().invoke(cli, args)
        assert result.exit_code == 1, result.output
        assert f"pid {holder.pid}" in result.output and "being written" in result.output
        assert not (out / "manifest.jsonl").exists()
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    assert json.loads((out / "dataset.json").read_text())["status"] == "complete"


def test_a_merge_cut_short_never_reads_as_finished(scenes, tmp_path, monkeypatch):
    """Issue #34: merge-shards marks its output unfinished before the first copy and finished
    after the last, so readers refuse a merge that was cut short."""
    import shutil

    from dualpixel.synthesis.dataset import merge_shards

    parts = []
    for k in range(2):
        parts.append(tmp_path / f"part{k}")
        synthesize_dataset(scenes, "rgbd", parts[-1], SynthConfig(**CONFIG), shard=(k, 2),
                           progress=False)
    copies = {"n": 0}
    real_copy = shutil.copyfile

    def copy_then_die(source, target, *args, **kwargs):
        copies["n"] += 1
        if copies["n"] == 7:
            raise KeyboardInterrupt  # a kill mid-merge (no cleanup runs after it)
        return real_copy(source, target, *args, **kwargs)

    monkeypatch.setattr(shutil, "copyfile", copy_then_die)
    with pytest.raises(KeyboardInterrupt):
        merge_shards(parts, tmp_path / "merged", progress=False)
    monkeypatch.setattr(shutil, "copyfile", real_copy)
    assert list((tmp_path / "merged").rglob("*.png"))  # some frames landed
    with pytest.raises(InputFileError, match="unfinished"):
        discover_dp_dataset(tmp_path / "merged", "train")


def _children(pid: int) -> list[int]:
    found = []
    for task in Path(f"/proc/{pid}/task").glob("*/children"):
        found += [int(p) for p in task.read_text().split()]
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except FileNotFoundError:
        return False
    return state != "Z"


def test_workers_die_with_their_parent(scenes, tmp_path):
    """Issue #34: `synth --workers 2` killed by SIGKILL leaves no worker behind (each watches
    its parent), and nothing is written after the kill."""
    command = [sys.executable, "-m", "dualpixel", "-q", "synth", "--input", str(scenes),
               "--output", str(tmp_path / "data"), "--lens-sets", "set0,set1,set2,set3,set4",
               "--workers", "2"]
    parent = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)
    deadline = time.monotonic() + 120
    workers: list[int] = []
    while time.monotonic() < deadline and len(workers) < 2:
        workers = [p for p in _children(parent.pid) if "spawn_main" in
                   Path(f"/proc/{p}/cmdline").read_bytes().decode(errors="replace")]
        time.sleep(0.2)
    assert len(workers) >= 2, "the workers never started"
    parent.send_signal(signal.SIGKILL)
    parent.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(p) for p in workers):
        time.sleep(0.1)
    assert not any(_alive(p) for p in workers), "a worker outlived its parent"


def _kill_when(child: subprocess.Popen, ready, what: str) -> None:
    """SIGKILL ``child``'s process group once ``ready()`` holds (polled), as a machine that
    loses power or an OOM killer stops it: no cleanup runs."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and child.poll() is None:
        if ready():
            os.killpg(child.pid, signal.SIGKILL)
            break
        time.sleep(0.005)
    assert child.wait(timeout=60) == -signal.SIGKILL, f"{what} finished before it was killed"


# Each child slows its own writes down (a sleep after each) so the kill lands mid-run; the kill
# itself is a real signal.
_SCENES_CHILD = textwrap.dedent("""
    import sys, time
    from dualpixel.synthesis import scenes
    write = scenes._write_sequence
    def slow(*args):
        write(*args)
        time.sleep(0.3)
    scenes._write_sequence = slow
    scenes.write_scene_folder(sys.argv[1], 6, scenes.SceneConfig(width=96, height=64, frames=2,
                              layout="photo"), seed=4, progress=False)
""")

_MERGE_CHILD = textwrap.dedent("""
    import shutil, sys, time
    from dualpixel.synthesis.dataset import merge_shards
    copy = shutil.copyfile
    def slow(*args, **kwargs):
        time.sleep(0.05)
        return copy(*args, **kwargs)
    shutil.copyfile = slow
    merge_shards(sys.argv[2:], sys.argv[1], progress=False)
""")


def _child(script: str, *args) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", script, *map(str, args)],
                            start_new_session=True,
                            env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})


def test_killed_scenes_rerun_to_the_uninterrupted_bytes(tmp_path):
    """Issue #76: `scenes` killed by SIGKILL after two of six sequences, then run again, leaves
    the folder an uninterrupted run writes, byte for byte (lock file included)."""
    config = SceneConfig(width=96, height=64, frames=2, layout="photo")
    write_scene_folder(tmp_path / "reference", 6, config, seed=4, progress=False)
    killed = tmp_path / "killed"
    child = _child(_SCENES_CHILD, killed)
    _kill_when(child, lambda: len(list(killed.glob("seq_*/depth/frame_0001.npy"))) >= 2,
               "scenes")
    assert json.loads((killed / "scenes.json").read_text())["status"] == "incomplete"
    write_scene_folder(killed, 6, config, seed=4, progress=False)
    assert every_file(killed) == every_file(tmp_path / "reference")


def test_killed_merge_rerun_to_the_uninterrupted_bytes(scenes, tmp_path):
    """Issue #76: `merge-shards` killed by SIGKILL mid-copy is never read as a dataset; merged
    again into the same folder, it is the uninterrupted merge byte for byte; a folder holding
    anything else is still refused."""
    from dualpixel.errors import OutputFileError
    from dualpixel.synthesis.dataset import merge_shards

    parts = []
    for k in range(2):
        parts.append(tmp_path / f"part{k}")
        synthesize_dataset(scenes, "rgbd", parts[-1], SynthConfig(**CONFIG), shard=(k, 2),
                           progress=False)
    merge_shards(parts, tmp_path / "reference", progress=False)
    killed = tmp_path / "killed"
    child = _child(_MERGE_CHILD, killed, *parts)
    _kill_when(child, lambda: len(list(killed.rglob("*.png"))) >= 10, "merge-shards")
    with pytest.raises(InputFileError, match="unfinished"):
        discover_dp_dataset(killed, "train")
    merge_shards(parts, killed, progress=False)
    assert every_file(killed) == every_file(tmp_path / "reference")
    with pytest.raises(OutputFileError, match="not empty"):  # a finished merge is not redone
        merge_shards(parts, killed, progress=False)
