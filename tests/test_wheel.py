"""The built wheel holds what an installed package needs (issue #13): weights with their model
card, py.typed, the licence, the NIQE model, the demo scene, the shipped cameras, and the
project URLs."""

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    source = tmp_path_factory.mktemp("source")  # a copy: the build leaves build/ behind
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, source / name)
    shutil.copytree(ROOT / "src", source / "src",
                    ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    subprocess.run([sys.executable, "-m", "pip", "wheel", str(source), "--no-deps",
                    "--no-build-isolation", "--quiet", "-w", str(out)], check=True)
    (path,) = out.glob("dualpixel-*.whl")
    return path


def test_wheel_contents(wheel):
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
        metadata = next(n for n in names if n.endswith(".dist-info/METADATA"))
        text = archive.read(metadata).decode()
    from dualpixel.weights import WEIGHTS

    shipped = {n for n in names if n.endswith(".safetensors")}
    assert shipped == {f"dualpixel/weights/{w.file}" for w in WEIGHTS.values()}
    assert len(shipped) <= 2  # the default and one alternative (issue #32)
    for needed in ("dualpixel/py.typed", "dualpixel/weights/registry.json",
                   "dualpixel/weights/MODEL_CARD.md", "dualpixel/evaluation/niqe_builtin.npz",
                   "dualpixel/demo_data/canon_scene_01/LICENSE.md",
                   "dualpixel/cameras/pixel4.json", "dualpixel/cameras/canon-840-linear.json"):
        assert needed in names, needed
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert "Project-URL: Source" in text and "License-Expression: MIT" in text
    assert wheel.stat().st_size < 80e6
