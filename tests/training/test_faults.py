"""A training run killed (SIGKILL) while it writes a checkpoint resumes to the same weights as an
uninterrupted run."""

import json
import os
import signal
import subprocess
import sys
import textwrap

import pytest
import torch

from dualpixel.io.atomic import PARTIAL_GLOB
from dualpixel.models import load_model
from dualpixel.training import train
from tests.training.test_trainer import tiny_config

# Runs the tiny training in a child process that kills itself (SIGKILL: no cleanup, no finally)
# at the chosen moment of the second epoch's checkpoint.
_CHILD = textwrap.dedent("""
    import os, pathlib, signal, sys
    from dualpixel.training import load_config, train
    from dualpixel.training import trainer

    moment, data, output = sys.argv[1], sys.argv[2], sys.argv[3]
    calls = {"state": 0, "weights": 0}
    real_write_bytes, real_save_model = pathlib.Path.write_bytes, trainer.save_model

    def write_bytes(self, data):  # last_state.pt's temporary file
        if self.name.startswith(".last_state."):
            calls["state"] += 1
            if moment == "state" and calls["state"] == 2:
                real_write_bytes(self, bytes(data)[: len(data) // 2])  # half a file
                os.kill(os.getpid(), signal.SIGKILL)
        return real_write_bytes(self, data)

    def save_model(path, *args, **kwargs):  # last.safetensors, after the state file
        calls["weights"] += 1
        if moment == "weights" and calls["weights"] == 2:
            os.kill(os.getpid(), signal.SIGKILL)
        return real_save_model(path, *args, **kwargs)

    pathlib.Path.write_bytes, trainer.save_model = write_bytes, save_model
    values = dict(model="rdpd", width=0.125, synthetic_data=data, patch_size=32,
                  sequence_batch=2, sequence_frames=2, epochs=2, iterations_per_epoch=3,
                  workers=0, learning_rate=1e-3, tensorboard=False, lr_halve_every=1,
                  threads=1)
    train(load_config(None, values), output, progress=False)
""")


@pytest.mark.parametrize("moment", ["state", "weights"])
def test_kill_during_checkpoint_write_resumes_to_the_same_weights(
        tiny_synthetic_dataset, tmp_path, moment):
    # one thread in both processes: a machine with other thread counts rounds differently, and
    # resume promises the uninterrupted run's weights on the same machine settings
    config = tiny_config(tiny_synthetic_dataset, lr_halve_every=1, threads=1)
    straight = train(config, tmp_path / "straight", progress=False)

    killed = tmp_path / "killed"
    child = subprocess.run(
        [sys.executable, "-c", _CHILD, moment, str(tiny_synthetic_dataset), str(killed)],
        capture_output=True, text=True, timeout=300,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
    )
    assert child.returncode == -signal.SIGKILL, child.stderr
    if moment == "state":  # killed mid-write: epoch 1 is the last consistent checkpoint
        assert list(killed.glob(PARTIAL_GLOB))
        assert torch.load(killed / "last_state.pt", weights_only=False)["epoch"] == 0
    else:  # killed after the state file: last.safetensors still holds epoch 1
        assert torch.load(killed / "last_state.pt", weights_only=False)["epoch"] == 1

    resumed = train(config, killed, resume=True, progress=False)
    assert resumed.step == straight.step == 6
    assert not list(killed.glob(PARTIAL_GLOB))
    a = load_model(tmp_path / "straight" / "last.safetensors").state_dict()
    b = load_model(killed / "last.safetensors").state_dict()
    for key in a:
        torch.testing.assert_close(a[key], b[key], rtol=0, atol=0)
    history = (killed / "history.jsonl").read_text().splitlines()
    assert len(history) == 2


# Runs the tiny training with a state written after every iteration (checkpoint_minutes: 0) and
# SIGKILLs itself once the chosen one (1-based, counted over the run) is in place.
_CHILD_WITHIN = textwrap.dedent("""
    import os, signal, sys
    from dualpixel.training import load_config, train
    from dualpixel.training import trainer

    kill_after, data, output = int(sys.argv[1]), sys.argv[2], sys.argv[3]
    real_save_state, written = trainer._save_state, []

    def save_state(path, *args, **kwargs):
        real_save_state(path, *args, **kwargs)
        if path.name == trainer.STEP_STATE:
            written.append(path)
            if len(written) == kill_after:
                os.kill(os.getpid(), signal.SIGKILL)

    trainer._save_state = save_state
    values = dict(model="rdpd", width=0.125, synthetic_data=data, patch_size=32,
                  sequence_batch=2, sequence_frames=2, epochs=2, iterations_per_epoch=3,
                  workers=0, learning_rate=1e-3, tensorboard=False, lr_halve_every=1,
                  threads=1, checkpoint_minutes=0.0)
    train(load_config(None, values), output, progress=False)
""")


def _kill_within(data, output, kill_after):
    child = subprocess.run(
        [sys.executable, "-c", _CHILD_WITHIN, str(kill_after), str(data), str(output)],
        capture_output=True, text=True, timeout=300,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
    )
    assert child.returncode == -signal.SIGKILL, child.stderr


def _same_weights(a_folder, b_folder):
    a = load_model(a_folder / "last.safetensors").state_dict()
    b = load_model(b_folder / "last.safetensors").state_dict()
    for key in a:
        torch.testing.assert_close(a[key], b[key], rtol=0, atol=0)


# states are written after iterations 1 and 2 of each 3-iteration epoch: the 1st is within the
# first epoch (no epoch finished yet), the 3rd within the second
@pytest.mark.parametrize("kill_after", [1, 3])
def test_kill_within_an_epoch_resumes_from_there_to_the_same_weights(
        tiny_synthetic_dataset, tmp_path, kill_after):
    from dualpixel.training.trainer import STEP_STATE

    config = tiny_config(tiny_synthetic_dataset, lr_halve_every=1, threads=1,
                         checkpoint_minutes=0.0)
    straight = train(config, tmp_path / "straight", progress=False)
    killed = tmp_path / "killed"
    _kill_within(tiny_synthetic_dataset, killed, kill_after)
    state = torch.load(killed / STEP_STATE, weights_only=False)
    assert (state["epoch"], state["iteration"], state["step"]) == (kill_after // 3, 1,
                                                                    kill_after // 3 * 3 + 1)
    assert (killed / "last_state.pt").is_file() == (kill_after == 3)

    resumed = train(config, killed, resume=True, progress=False)
    assert resumed.step == straight.step == 6
    assert not (killed / STEP_STATE).exists()  # each epoch's checkpoint removes it
    _same_weights(tmp_path / "straight", killed)
    history = [json.loads(line) for line in (killed / "history.jsonl").read_text().splitlines()]
    assert [r["loss"] for r in history] == [r["loss"] for r in straight.history]


def test_a_stale_within_epoch_state_is_not_resumed(tiny_synthetic_dataset, tmp_path):
    """A ``step_state.pt`` of an epoch whose own checkpoint followed it (a kill between the two
    writes) is removed on resume, not trained from again."""
    from dualpixel.training.trainer import STEP_STATE

    config = tiny_config(tiny_synthetic_dataset, lr_halve_every=1, threads=1,
                         checkpoint_minutes=0.0)
    train(config, tmp_path / "straight", progress=False)
    killed = tmp_path / "killed"
    _kill_within(tiny_synthetic_dataset, killed, 2)  # within epoch 1, after its iteration 2
    stale = (killed / STEP_STATE).read_bytes()
    one_epoch = tiny_config(tiny_synthetic_dataset, lr_halve_every=1, threads=1,
                            checkpoint_minutes=0.0, epochs=1)
    train(one_epoch, killed, resume=True, progress=False)
    (killed / STEP_STATE).write_bytes(stale)  # as if the kill came before its removal
    result = train(config, killed, resume=True, progress=False)
    assert result.step == 6 and not (killed / STEP_STATE).exists()
    _same_weights(tmp_path / "straight", killed)


class _Payload:
    """Pickles as a call that creates ``marker``: what a crafted state file would run."""

    def __init__(self, marker: str) -> None:
        self.marker = marker

    def __reduce__(self):
        return (open, (self.marker, "w"))


def test_a_crafted_state_file_runs_no_code(tiny_synthetic_dataset, tmp_path):
    from dualpixel.errors import InputFileError

    out = tmp_path / "run"
    config = tiny_config(tiny_synthetic_dataset, epochs=1)
    train(config, out, progress=False)
    marker = tmp_path / "pwned"
    torch.save({"model": _Payload(str(marker)), "epoch": 0}, out / "last_state.pt")
    longer = tiny_config(tiny_synthetic_dataset, epochs=2)
    with pytest.raises(InputFileError, match=r"last_state\.pt.*safely"):
        train(longer, out, resume=True, progress=False)
    assert not marker.exists()
    # the trainer's own state files still resume (they hold tensors and plain containers only)
    fresh = tmp_path / "fresh"
    train(config, fresh, progress=False)
    result = train(longer, fresh, resume=True, progress=False)
    assert result.step == 6 and len(result.history) == 2


def _non_mapping(state):
    return [1, 2, 3]


def _no_optimizer(state):
    del state["optimizer"]
    return state


def _wrong_shape(state):
    name = next(iter(state["model"]))
    state["model"][name] = torch.zeros(7, 7)
    return state


def _epoch_text(state):
    state["epoch"] = "one"
    return state


def _emptied(state):
    return {}


def _negative_step(state):
    state["step"] = -3
    return state


@pytest.mark.parametrize("spoil, says", [
    (_non_mapping, "not a mapping"), (_no_optimizer, "no 'optimizer' entry"),
    (_wrong_shape, "does not fit"), (_epoch_text, "'epoch' is a str"),
    (_emptied, "no 'model' entry"), (_negative_step, "a negative epoch or step"),
])
def test_a_hostile_state_is_refused_by_name_on_resume(tiny_synthetic_dataset, tmp_path,
                                                       spoil, says):
    from dualpixel.errors import InputFileError

    config = tiny_config(tiny_synthetic_dataset, epochs=1, iterations_per_epoch=1)
    train(config, tmp_path / "run", progress=False)
    path = tmp_path / "run" / "last_state.pt"
    torch.save(spoil(torch.load(path, weights_only=True)), path)
    longer = tiny_config(tiny_synthetic_dataset, epochs=2, iterations_per_epoch=1)
    with pytest.raises(InputFileError, match=says) as caught:
        train(longer, tmp_path / "run", resume=True, progress=False)
    assert "last_state.pt" in str(caught.value)


def test_corrupt_run_records_are_refused_by_name(tiny_synthetic_dataset, tmp_path):
    from dualpixel.errors import InputFileError

    config = tiny_config(tiny_synthetic_dataset, epochs=1, iterations_per_epoch=1)
    train(config, tmp_path / "run", progress=False)
    (tmp_path / "run" / "init.json").write_text("[" * 100_000)
    longer = tiny_config(tiny_synthetic_dataset, epochs=2, iterations_per_epoch=1)
    with pytest.raises(InputFileError, match=r"init\.json"):
        train(longer, tmp_path / "run", resume=True, progress=False)
