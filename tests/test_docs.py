"""`make docs`: the API reference builds from the docstrings without a warning."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_api_reference_builds_without_warnings(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path)],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "WARNING" not in done.stderr, done.stderr[-3000:]
    page = (tmp_path / "api" / "calibration" / "index.html").read_text()
    assert "calibrate_camera" in page and "DPCamera" in page


def _command_lines(text: str) -> list[str]:
    """Each ``dualpixel ...`` invocation in the fenced code blocks of ``text``, continuation
    lines joined and comments dropped."""
    lines, inside, current = [], False, ""
    for raw in text.splitlines():
        if raw.lstrip().startswith("```"):
            inside, current = not inside, ""
            continue
        if not inside:
            continue
        line = raw.split("  #")[0].rstrip()
        current = f"{current} {line.strip()}" if current else line.strip()
        if current.endswith("\\"):
            current = current[:-1]
            continue
        if current.startswith("dualpixel "):
            lines.append(current)
        current = ""
    return lines


def test_every_documented_command_line_names_real_commands_and_options():
    """The README, the guide and the model card use only commands and options that exist."""
    import click

    from dualpixel.cli.main import cli

    documents = [ROOT / "README.md", ROOT / "docs" / "guide.md",
                 ROOT / "src" / "dualpixel" / "weights" / "MODEL_CARD.md"]
    checked = 0
    for document in documents:
        for line in _command_lines(document.read_text()):
            words = line.replace("[", " ").replace("]", " ").split()[1:]
            words = [w for w in words if w not in ("-q", "--quiet")]
            command: click.Command = cli
            while isinstance(command, click.Group) and words and words[0] in command.commands:
                command = command.commands[words.pop(0)]
            assert not isinstance(command, click.Group), f"{document.name}: {line}"
            known = {o for p in command.params for o in getattr(p, "opts", [])}
            known |= {o for p in command.params for o in getattr(p, "secondary_opts", [])}
            for word in words:
                option = word.split("=")[0]
                if option.startswith("--") or (option.startswith("-") and len(option) == 2
                                               and option[1].isalpha()):
                    assert option in known, f"{document.name}: {option} in {line!r}"
            checked += 1
    assert checked > 40  # the documents hold that many examples


def test_the_sample_training_config_trains(tiny_synthetic_dataset, tmp_path):
    """The shipped example `finetune`, by name as the guide gives it, on tiny data for two
    iterations (the wheel holds it: issue #73)."""
    import yaml
    from click.testing import CliRunner

    from dualpixel.cli.main import cli

    sample = ROOT / "src" / "dualpixel" / "examples" / "finetune.yaml"
    config = yaml.safe_load(sample.read_text())
    assert config["init_weights"] == "rdpd-light.v15"
    result = CliRunner().invoke(cli, [
        "train", "--config", "finetune", "--output", str(tmp_path / "run"), "--no-progress",
        "--set", f"synthetic_data={tiny_synthetic_dataset}",
        "--set", f"val_data={tiny_synthetic_dataset}", "--set", "epochs=1",
        "--set", "iterations_per_epoch=2", "--set", "patch_size=64", "--set", "val_limit=1",
        "--set", "tensorboard=false", "--set", "threads=1"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "run" / "last.safetensors").is_file()
