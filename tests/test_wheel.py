"""The built wheel holds what an installed package needs: weights with their model
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
    # the default, the tag it was fine-tuned from (its recipe's start) and one alternative
    assert len(shipped) <= 3
    for needed in ("dualpixel/py.typed", "dualpixel/weights/registry.json",
                   "dualpixel/weights/MODEL_CARD.md", "dualpixel/evaluation/niqe_builtin.npz",
                   "dualpixel/demo_data/canon_scene_01/LICENSE.md",
                   "dualpixel/cameras/pixel4.json", "dualpixel/cameras/canon-840-linear.json",
                   "dualpixel/examples/finetune.yaml"):  # the guide's `--config finetune`
        assert needed in names, needed
    from dualpixel.synthesis.textures import PHOTOGRAPH_NAMES

    for name in PHOTOGRAPH_NAMES:  # synthesis reads its textures from the package alone
        assert f"dualpixel/synthesis/photographs/{name}.png" in names, name
    assert "dualpixel/synthesis/photographs/SOURCES.md" in names
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert "Project-URL: Source" in text and "License-Expression: MIT" in text
    assert wheel.stat().st_size < 95e6  # under PyPI's 100 MB per file


def test_the_installed_wheel_works_outside_the_clone(wheel, tmp_path):
    """The wheel installed on its own (no source tree on the path), run from a folder outside
    the clone: the README's Python example and ``dualpixel demo``."""
    import site

    target = tmp_path / "installed"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--quiet", "--target",
                    str(target), str(wheel)], check=True)
    # -S: no site processing, so the clone's editable install is invisible; the dependencies
    # come from this environment's site-packages, the package from the wheel alone
    env = {"PYTHONPATH": ":".join([str(target), *site.getsitepackages()]),
           "PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "TQDM_DISABLE": "1"}
    body = """
rng = np.random.default_rng(0)
rgb = rng.uniform(0.1, 0.9, (64, 96, 3)).astype(np.float32)
depth_m = np.linspace(1.0, 6.0, 96, dtype=np.float32)[None].repeat(64, 0)
frame = dualpixel.synthesize(rgb, depth_m, lens_set="dslr-840", camera="canon-840-linear",
                             noise_model="poisson-gaussian",
                             noise_sigmas=(0.006, 0.009, 0.013, 0.018, 0.025), seed=0)
sharp = dualpixel.deblur(frame["left"], frame["right"], device="cpu")
print(dualpixel.check_views(frame["left"], frame["right"], frame["combined"]))
print("PSNR", repr(dualpixel.psnr(sharp, frame["target"])), sorted(dualpixel.list_models()))
"""
    example = ("import numpy as np\nimport dualpixel\n"
               f"assert dualpixel.__file__.startswith({str(target)!r}), dualpixel.__file__\n"
               + body)
    run = subprocess.run([sys.executable, "-S", "-c", example], cwd=tmp_path, env=env,
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]
    # the installed wheel deblurs as the clone does, number for number
    import contextlib
    import io

    import numpy as np

    import dualpixel

    here = io.StringIO()
    with contextlib.redirect_stdout(here):
        exec(body, {"np": np, "dualpixel": dualpixel})
    ours = next(line for line in here.getvalue().splitlines() if line.startswith("PSNR"))
    assert ours in run.stdout, (ours, run.stdout)
    demo = subprocess.run([sys.executable, "-S", "-m", "dualpixel", "demo", "--output",
                           str(tmp_path / "demo"), "--frames", "1", "--device", "cpu"],
                          cwd=tmp_path, env=env, capture_output=True, text=True)
    assert demo.returncode == 0, demo.stderr[-2000:]
    assert (tmp_path / "demo" / "index.html").is_file()


def test_runtime_dependencies_are_held_to_the_tested_majors():
    """Every runtime dependency has an upper bound below its next major version (a major that
    changed under the project once broke it), and the versions installed here, the tested
    ones, lie inside every range. tifffile's versions are dates: no major to hold."""
    import importlib.metadata

    from packaging.requirements import Requirement

    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    for spec in project["dependencies"]:
        requirement = Requirement(spec)
        if requirement.name != "tifffile":
            assert any(s.operator == "<" for s in requirement.specifier), spec
        installed = importlib.metadata.version(requirement.name)
        assert requirement.specifier.contains(installed, prereleases=True), (spec, installed)
