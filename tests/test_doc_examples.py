"""Every command line and Python example of the README and the guide runs.

Each document's commands run in its order in a folder of their own, as a reader would type
them, on small inputs made here: sizes shrink, worker counts and devices become one CPU
process, ``../shared`` is a stand-in of the same layout (a few crops of its pairs), a command
that trains for hours runs as ``--dry-run`` (a training run: two iterations), and
``[optional]`` parts run without and then with (:func:`tiny`). What stands in for the files a
reader brings (``L.png``, ``my-pairs/``, ``IMG_0001.CR2``, ...) is :func:`_bring`; captures of
a pattern an earlier command drew are :data:`CAPTURES`. A command whose outcome here is a
refusal (a release of a run this folder does not hold) is in :data:`REFUSED` and must fail
cleanly, naming what is missing.
"""

from __future__ import annotations

import glob
import itertools
import re
import shlex
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from tests.conftest import write_photographs
from tests.test_docs import _command_lines

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
#: Commands whose documented use needs what this folder does not hold (a finished run: the
#: recipes run as --dry-run here), with what the refusal must name (a clean error, no
#: traceback).
REFUSED = {"dualpixel release runs/rdpd-light --tag rdpd-light.v12": "runs/rdpd-light",
           # its earlier phases' weights come from the run folder, or --tag-file: the tag
           # that phase made no longer ships
           "dualpixel reproduce recipes/rdpd-light.yaml --output runs/rdpd-light --from "
           "joint-cycle --dry-run": "--tag-file rdpd-light-stage11=PATH",
           # the stand-in dp-real-nogt holds one Pixel 4 pair
           "dualpixel adapt ../shared/data/dp-real-nogt --select pixel-gif-0? --select "
           "pixel-mp4-0? -o runs/adapt-pixel4 --camera pixel4 --scenes 2 --epochs 1 "
           "--iterations 2 --patch-size 64 --scene-size 128x96 --threads 1 --no-progress":
           "adapt needs at least 2"}
#: Canon scenes (by number) whose 480x288 middles `calibrate camera` takes.
CALIBRATED = [2, 5]
#: A training run of two iterations on 64-px crops, whatever the config says.
TINY_TRAINING = "".join(f" --set {setting}" for setting in (
    "epochs=1", "iterations_per_epoch=2", "patch_size=64", "val_limit=1", "threads=1",
    "tensorboard=false"))
#: Size of every stand-in image (px): the smallest the target-free checks take (4 x 2 blocks).
WIDTH, HEIGHT = 128, 96


def tiny(line: str) -> list[list[str]]:
    """The argument lists that run ``line`` (a documented ``dualpixel ...`` command) on tiny
    inputs: one per value of ``$K`` and per ``[optional]`` part (without, then with)."""
    line = re.sub(r"--size \d+x\d+", lambda m: "--size 320x240" if "pattern" in line else
                  "--size 64x64" if "export" in line else f"--size {WIDTH}x{HEIGHT}", line)
    line = re.sub(r"--sequences \d+", "--sequences 2", line)
    line = re.sub(r"--frames \d+", "--frames 2", line)
    line = re.sub(r"--workers \d+", "--workers 1", line)
    line = re.sub(r"--loader-workers \d+", "--loader-workers 0", line)
    line = re.sub(r"--threads \d+", "--threads 1", line)
    line = line.replace("--device cuda", "--device cpu")
    if line.startswith("dualpixel train"):
        line += TINY_TRAINING
    if line.startswith("dualpixel adapt"):  # two steps on tiny crops and scenes
        line += (" --scenes 2 --epochs 1 --iterations 2 --patch-size 64 --scene-size 128x96"
                 " --threads 1 --no-progress")
    if line.startswith("dualpixel reproduce") and "--dry-run" not in line:
        line += " --dry-run"  # hours of training: the plan, every step and phase checked
    optional = re.findall(r"\[([^\]]*)\]", line)
    plain = re.sub(r"\s*\[[^\]]*\]", "", line)
    variants = [plain] + [f"{plain} {part}" for part in optional]
    if "$K" in line:
        variants = [v.replace("$K", str(k)) for v in variants for k in range(4)]
    runs = []
    for variant in variants:
        words = []
        for word in shlex.split(variant)[1:]:
            words += sorted(glob.glob(word)) if "*" in word else [word]
        runs.append(words)
    return runs


def _views(seed: int, width: int = WIDTH, height: int = HEIGHT) -> dict[str, np.ndarray]:
    """A tiny DP frame of the shipped model's training kind (float32 (H, W, 3) in [0, 1])."""
    import dualpixel
    from dualpixel.synthesis.scenes import SceneConfig, render_scene

    (rgb, depth), = render_scene(seed, SceneConfig(width=width, height=height, frames=1,
                                                   layout="photo"))[0]
    return dualpixel.synthesize(rgb, depth, seed=seed)


def _png(path: Path, image: np.ndarray, bits: int = 8) -> None:
    """``image`` (float, [0, 1]) as a PNG of ``bits`` bits, its folder made first."""
    from dualpixel.io.images import write_png

    path.parent.mkdir(parents=True, exist_ok=True)
    write_png(path, np.asarray(image, np.float32), bit_depth=bits)


def _crops(source: Path, target: Path, scenes: list[int], size: tuple[int, int]) -> None:
    """The middle ``size`` (width, height) px of the scene folders of ``source`` numbered
    ``scenes`` in name order, every image of each."""
    width, height = size
    folders = sorted(p for p in source.iterdir() if p.is_dir())
    for scene in (folders[index] for index in scenes):
        for image in scene.glob("*.png"):
            full = cv2.imread(str(image), cv2.IMREAD_UNCHANGED)
            top, left = (full.shape[0] - height) // 2, (full.shape[1] - width) // 2
            (target / scene.name).mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(target / scene.name / image.name),
                        full[top : top + height, left : left + width])


def _shared(root: Path) -> None:
    """../shared/data stand-ins of the same layout: two pairs of each set, cropped; the Canon
    crops as large as `calibrate camera` needs (20 blurred, textured blocks), of scenes whose
    middle is aligned with its target (scene_00's is 1.3 px off, which calibration refuses)."""
    for name, scenes, size in (("canon-dp-real", CALIBRATED, (480, 288)),
                               ("canon-dp-real-hd", CALIBRATED, (480, 288)),
                               ("dp-real-nogt", [0, 1], (2 * WIDTH, 2 * HEIGHT))):
        _crops(SHARED / name, root / name, scenes, size)


def _bring(folder: Path, dataset: str) -> None:
    """What a reader brings to the examples: views, captures, weights files, configs (their
    own training config: the sample on ``dataset``)."""
    sample = (ROOT / "src" / "dualpixel" / "examples" / "finetune.yaml").read_text()
    (folder / "my.yaml").write_text(re.sub(r"(synthetic_data|val_data): data\b",
                                           rf"\1: {dataset}", sample))

    frame = _views(1)
    _png(folder / "L.png", frame["left"])
    _png(folder / "R.png", frame["right"])
    grey = [0.06 + 0.9 * frame[k][..., 1] for k in ("left", "right")]  # linear, above black
    for name, view in zip(("pL.png", "pR.png"), grey):
        _png(folder / name, (1024 + view * (16383 - 1024)) / 65535, bits=16)
    for index in range(2):  # Pixel DP captures as the public releases store them: turned
        for role, name in (("left", "result_leftPd_center.png"),  # clockwise, 16-bit grey
                           ("right", "result_rightPd_center.png")):
            view = np.rot90(cv2.imread(str(folder / f"p{role[0].upper()}.png"),
                                       cv2.IMREAD_UNCHANGED), -1)
            (folder / "captures" / f"capture{index}").mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(folder / "captures" / f"capture{index}" / name),
                        np.ascontiguousarray(view))
    for index in range(2):
        frame = _views(2 + index)
        _png(folder / "left_frames" / f"{index:04d}.png", frame["left"])
        _png(folder / "right_frames" / f"{index:04d}.png", frame["right"])
    _crops(SHARED / "canon-dp-real", folder / "my-pairs", [6], (480, 288))
    for index, name in enumerate("abc"):  # DPDD layout; sharp enough for a NIQE fit
        scene = SHARED / "canon-dp-real" / f"scene_{CALIBRATED[index % 2] + index // 2:02d}"
        for role, image in (("l/source", "view0"), ("r/source", "view1"), ("c/source", "input"),
                            ("c/target", "target")):
            (folder / "dpdd" / f"test_{role}").mkdir(parents=True, exist_ok=True)
            shutil.copy(scene / f"{image}.png", folder / "dpdd" / f"test_{role}" / f"{name}.png")
    (folder / "indoor_outdoor.csv").write_text("a,indoor\nb,outdoor\nc,outdoor\n")
    write_photographs(folder / "my-photos")
    for name in ("predictions", "targets"):
        shutil.copytree(folder / "dpdd" / "test_c" / "target", folder / name)
    for view in ("left", "right"):  # measured PSFs: one of the Pixel 4's
        np.save(folder / f"{view}.npy", np.load(SHARED / "pixel4-measured-psf" / f"{view}.npy")[:1])
    shutil.copy(ROOT / "src" / "dualpixel" / "cameras" / "canon-840.json", folder / "camera.json")
    from tests.models.test_keras_import import keras_shapes, write_keras_file

    write_keras_file(folder / "dpdnet_weights.hdf5", keras_shapes())  # the authors' layout
    for index, sequence in enumerate(("SEQ1", "SEQ3")):  # SYNTHIA-SF: RGB, depth in 24-bit code
        frame = _views(20 + index)
        _png(folder / "SYNTHIA-SF" / sequence / "RGBLeft" / "0000.png", frame["target"])
        metres = np.where(np.arange(WIDTH) < WIDTH // 2, 3.0, 30.0) * np.ones((HEIGHT, 1))
        code = np.rint(metres / 1000 * (2**24 - 1)).astype(np.int64)
        bgr = np.stack((code // 65536, (code // 256) % 256, code % 256), -1).astype(np.uint8)
        (folder / "SYNTHIA-SF" / sequence / "DepthLeft").mkdir()
        cv2.imwrite(str(folder / "SYNTHIA-SF" / sequence / "DepthLeft" / "0000.png"), bgr)


def _canon_raw(path: Path) -> None:
    """``path`` as a two-frame raw file of a 512x384 frame that LibRaw reads as a Dual Pixel
    RAW (A+B, then A; a DNG written by tifffile, as ``tests/data/test_dpraw.py`` makes them)."""
    from tests.data.test_dpraw import SRGB_FROM_XYZ, _raw_of, _two_frame_dng

    frame = _views(5, 512, 384)
    _two_frame_dng(path, _raw_of(frame["left"], frame["right"]), SRGB_FROM_XYZ)


def _capture_disks(folder: Path) -> None:
    """``disks-L.png``/``disks-R.png``: DP views of ``disks.png`` defocused by a 4-px CoC
    (half the light each, a display black level), 16-bit."""
    from scipy.signal import fftconvolve

    from dualpixel.optics.psf import PSFParams, dp_psf

    pattern = cv2.imread(str(folder / "disks.png"), cv2.IMREAD_GRAYSCALE) / 255.0
    kernels = dp_psf(4.0, PSFParams(n=6, alpha=0.6, beta=0.3), size=21)
    for name, kernel in (("disks-L.png", kernels.left), ("disks-R.png", kernels.right)):
        view = 0.05 + 0.5 * fftconvolve(pattern, 2 * kernel.numpy(), "same")
        _png(folder / name, view, bits=16)


def _capture_squares(folder: Path) -> None:
    """``grid.png``: ``squares.png`` as a lens with barrel distortion shows it."""
    import torch

    from dualpixel.optics.distortion import DISTORTION_PRESETS, distort_image

    pattern = cv2.imread(str(folder / "squares.png"), cv2.IMREAD_GRAYSCALE) / 255.0
    image = distort_image(torch.from_numpy(pattern.astype(np.float32))[None],
                          DISTORTION_PRESETS["set3"])[0].numpy()
    _png(folder / "grid.png", image)


#: Captures a reader makes of a pattern an earlier command drew, made before the command that
#: reads them.
CAPTURES = {"calibrate estimate-psf": _capture_disks, "calibrate fit-distortion": _capture_squares}


def _run(words: list[str], where: str) -> None:
    result = CliRunner().invoke(cli, words)
    shown = " ".join(words)
    expected = REFUSED.get(f"dualpixel {shown}")
    if expected is not None:
        assert result.exit_code != 0 and expected in result.output, f"{where}: {shown}"
        assert "Traceback" not in result.output, f"{where}: {shown}\n{result.output}"
        return
    assert result.exit_code == 0, f"{where}: dualpixel {shown}\n{result.output[-3000:]}"
    if "--dry-run" not in words:  # what the command says it writes is there
        for flag, value in itertools.pairwise(words):
            if flag in ("--output", "-o", "--figure", "--save"):
                assert Path(value).exists(), f"{where}: dualpixel {shown} wrote no {value}"


@pytest.mark.parametrize(("document", "dataset"), [("README.md", "data"),
                                                  ("docs/guide.md", "photo-dp")])
def test_every_documented_command_runs(document, dataset, tmp_path, monkeypatch):
    if not SHARED.is_dir():
        pytest.skip("../shared/data is not here")
    work = tmp_path / "work"
    work.mkdir()
    _shared(tmp_path / "shared" / "data")
    for name in ("recipes", "docs"):
        (work / name).symlink_to(ROOT / name)
    _bring(work, dataset)
    _canon_raw(work / "IMG_0001.CR2")
    monkeypatch.chdir(work)
    lines = _command_lines((ROOT / document).read_text())
    assert len(lines) >= 20
    for line in lines:
        for command, capture in CAPTURES.items():
            if line.startswith(f"dualpixel {command}"):
                capture(work)
        for words in tiny(line):
            _run(words, document)


def _python_blocks(text: str) -> list[str]:
    """The fenced ``python`` blocks of ``text``."""
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


@pytest.mark.parametrize("document", ["README.md", "docs/guide.md"])
def test_every_documented_python_example_runs(document, tmp_path, monkeypatch):
    """Each Python block, with what it leaves to the reader given: ``rgb`` and ``depth_m`` (a
    tiny photo-like RGB-D frame), ``left_raw``/``right_raw`` (a phone's 14-bit green-only raw
    views above a black level of 1024), ``camera.json`` (a calibrated camera file); a GPU named
    in an example becomes the CPU."""
    from dualpixel.synthesis.scenes import SceneConfig, render_scene

    (rgb, depth_m), = render_scene(3, SceneConfig(width=WIDTH, height=HEIGHT, frames=1,
                                                  layout="photo"))[0]
    frame = _views(4)
    left_raw, right_raw = (np.rint(1024 + (0.06 + 0.9 * frame[k][..., 1]) * (16383 - 1024))
                           .astype(np.uint16) for k in ("left", "right"))
    shutil.copy(ROOT / "src" / "dualpixel" / "cameras" / "canon-840.json",
                tmp_path / "camera.json")
    monkeypatch.chdir(tmp_path)
    blocks = _python_blocks((ROOT / document).read_text())
    assert blocks
    for block in blocks:
        code = block.replace('device="cuda"', 'device="cpu"')
        namespace = {"rgb": rgb, "depth_m": depth_m, "left_raw": left_raw,
                     "right_raw": right_raw}
        exec(compile(code, f"{document} example", "exec"), namespace)
        if "sharp" in namespace:  # the deblurred example keeps the input's shape and kind
            assert namespace["sharp"].shape == namespace["frame"]["left"].shape
        if "sharp_raw" in namespace:  # raw views: back in their encoding, counts / 65535
            counts = namespace["sharp_raw"] * 65535.0
            assert counts.shape == left_raw.shape
            assert counts.mean() == pytest.approx((left_raw.mean() + right_raw.mean()) / 2,
                                                  rel=0.02)
