import json
import re
import shutil
import subprocess
from typing import ClassVar

import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.evaluation import psnr
from dualpixel.inference import Deblurrer
from dualpixel.models import load_model
from dualpixel.synthesis.frame import draw_sequence, synthesize_frame
from dualpixel.synthesis.scenes import SceneConfig, render_scene_sequence
from dualpixel.weights import ALIASES, DEFAULT_CHECKPOINT, WEIGHTS, resolve_checkpoint


def test_shipped_checkpoint_loads_and_improves_on_a_new_synthetic_sequence():
    path = resolve_checkpoint(DEFAULT_CHECKPOINT)
    assert path.stat().st_size < 60 * 2**20  # the wheel holds it and one more within 80 MB
    model = load_model(path)
    assert model.spec.name == "rdpd" and model.recurrent
    # A sequence with a scene seed never used for training data (0..39 train, 1000.. test).
    rgbd = render_scene_sequence(777, SceneConfig(width=256, height=192, frames=3))
    draw = draw_sequence(777, "set1", noise_sigmas=(0.01,))
    deblur = Deblurrer(model)
    before, after = [], []
    for index, (rgb, depth) in enumerate(rgbd):
        frame = synthesize_frame(rgb, depth, draw, noise_seed=index)
        hwc = {k: getattr(frame, k).permute(1, 2, 0).numpy() for k in
               ("left", "right", "combined", "target")}
        output = deblur(hwc["left"], hwc["right"])
        before.append(psnr(hwc["combined"], hwc["target"]))
        after.append(psnr(output, hwc["target"]))
    assert np.mean(after) > np.mean(before)


class _CountingBar:
    """A progress bar that counts its steps (issue #73: the demo's bar ended at 8/9)."""

    made: ClassVar[list] = []

    def __init__(self, *args, total=None, **kwargs):
        self.total, self.n = total, 0
        _CountingBar.made.append(self)

    def update(self, steps=1):
        self.n += steps

    def close(self):
        pass


def test_demo_writes_a_complete_report(tmp_path, monkeypatch):
    import dualpixel.demo

    monkeypatch.setattr(dualpixel.demo, "progress_bar", _CountingBar)
    out = tmp_path / "demo"
    result = CliRunner().invoke(cli, ["demo", "--output", str(out), "--frames", "2"])
    assert result.exit_code == 0, result.output
    [bar] = _CountingBar.made
    assert bar.n == bar.total == 6  # two frames made, two deblurred, figures, report
    assert "report:" in result.output and "PSNR input" in result.output
    page = (out / "index.html").read_text()
    images = re.findall(r'<img src="([^"]+)"', page)
    expected = {"views.gif", "all_in_focus.png", "depth.png", "defocus.png", "compare_000.png",
                "compare_001.png", "psfs.png"}
    assert expected <= set(images)
    for name in images:
        assert (out / name).stat().st_size > 1000
    metrics = json.loads((out / "metrics.json").read_text())
    assert len(metrics["frames"]) == 2 and metrics["mode"] == "procedural"
    for key in ("psnr", "ssim", "mae"):
        assert f"{metrics['mean']['output'][key]:.{3 if key != 'psnr' else 2}f}" in page
    from PIL import Image

    with Image.open(out / "views.gif") as gif:  # the DP views, alternating
        assert gif.n_frames == 2


def test_demo_accepts_a_users_pair_and_rgbd(tmp_path, shared_dir):
    scene = shared_dir / "data" / "canon-dp-real" / "scene_01"
    result = CliRunner().invoke(cli, ["demo", "--output", str(tmp_path / "pair"), "--left",
                                      str(scene / "view0.png"), "--right",
                                      str(scene / "view1.png"), "--target",
                                      str(scene / "target.png")])
    assert result.exit_code == 0, result.output
    metrics = json.loads((tmp_path / "pair" / "metrics.json").read_text())
    assert metrics["mode"] == "pair" and len(metrics["frames"]) == 1
    rgb, depth = render_scene_sequence(5, SceneConfig(width=96, height=64, frames=1))[0]
    from dualpixel.io.images import save_npy, write_png

    write_png(tmp_path / "rgb.png", rgb, bit_depth=8)
    save_npy(tmp_path / "depth.npy", depth)
    result = CliRunner().invoke(cli, ["demo", "--output", str(tmp_path / "rgbd"), "--rgb",
                                      str(tmp_path / "rgb.png"), "--depth",
                                      str(tmp_path / "depth.npy")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "rgbd" / "defocus.png").is_file()
    bad = CliRunner().invoke(cli, ["demo", "--output", str(tmp_path / "x"), "--left",
                                   str(scene / "view0.png")])
    assert bad.exit_code == 2 and "--right" in bad.output


def test_report_opens_in_headless_chromium(tmp_path):
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        pytest.skip("Debian's chromium is not installed (.ci/run installs it)")
    out = tmp_path / "demo"
    result = CliRunner().invoke(cli, ["demo", "--output", str(out), "--frames", "1"])
    assert result.exit_code == 0, result.output
    dom = subprocess.run(
        [browser, "--headless=new", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=8000",
         "--dump-dom", (out / "index.html").as_uri()],
        capture_output=True, text=True, timeout=120,
    ).stdout
    count = len(re.findall(r"<img ", (out / "index.html").read_text()))
    assert f"images ok: {count}/{count}" in dom, dom[-500:]


def test_registry_names_the_shipped_model():
    assert ALIASES[DEFAULT_CHECKPOINT] in WEIGHTS
    from dualpixel.errors import InputFileError

    with pytest.raises(InputFileError, match="nor a shipped name"):
        resolve_checkpoint("no-such-model")
