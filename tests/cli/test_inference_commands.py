import json

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.models import build_model, load_model, save_model


@pytest.fixture(scope="module")
def checkpoint(tiny_checkpoint):
    return tiny_checkpoint


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_deblur_pair_keeps_16_bits_and_checks_sizes(checkpoint, tmp_path, capfd):
    rng = np.random.default_rng(0)
    for name in ("l", "r"):
        cv2.imwrite(str(tmp_path / f"{name}.png"), rng.integers(0, 65535, (36, 52, 3), np.uint16))
    result = run("deblur", "--left", tmp_path / "l.png", "--right", tmp_path / "r.png",
                 "--output", tmp_path / "out.png", "--checkpoint", checkpoint, "--device", "cpu")
    assert result.exit_code == 0, result.output
    out = cv2.imread(str(tmp_path / "out.png"), cv2.IMREAD_UNCHANGED)
    assert out.dtype == np.uint16 and out.shape == (36, 52, 3)
    cv2.imwrite(str(tmp_path / "r.png"), np.zeros((30, 52, 3), np.uint8))
    bad = run("deblur", "--left", tmp_path / "l.png", "--right", tmp_path / "r.png",
              "--output", tmp_path / "o.png", "--checkpoint", checkpoint)
    assert bad.exit_code == 1 and "r.png" in bad.output and "differs" in bad.output
    (tmp_path / "r.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(100))  # a header, then zeros
    capfd.readouterr()
    bad = run("deblur", "--left", tmp_path / "l.png", "--right", tmp_path / "r.png",
              "--output", tmp_path / "o.png", "--checkpoint", checkpoint)
    assert bad.exit_code == 1 and "r.png: cannot be decoded" in bad.output
    assert "grfmt" not in capfd.readouterr().err  # our error alone, not the decoder's log too
    missing = run("deblur", "--left", tmp_path / "l.png", "--right", tmp_path / "l.png",
                  "--output", tmp_path / "o.png", "--checkpoint", tmp_path / "none.safetensors")
    assert missing.exit_code == 1 and "none.safetensors: checkpoint not found" in missing.output


def test_deblur_runs_a_frame_too_large_for_memory_in_tiles_and_says_so(checkpoint, tmp_path,
                                                                         monkeypatch):
    from dualpixel.inference import deblur as deblur_module

    rng = np.random.default_rng(1)
    for name in ("l", "r"):
        cv2.imwrite(str(tmp_path / f"{name}.png"), rng.integers(0, 255, (400, 600, 3), np.uint8))
    args = ("deblur", "--left", tmp_path / "l.png", "--right", tmp_path / "r.png",
            "--checkpoint", checkpoint, "--device", "cpu", "--precision", "fp32")
    # memory for batches of four 128-px tiles in half of it; the 600x400 frame does not fit
    room = 2 * deblur_module.pass_memory(load_model(checkpoint), 4 * 128**2)
    monkeypatch.setattr(deblur_module, "available_memory", lambda: room)
    result = run(*args, "--output", tmp_path / "auto.png")
    assert result.exit_code == 0, result.output
    assert "Warning: a 600x400 frame needs about" in result.output
    assert "tiles of" in result.output and "UserWarning" not in result.output
    monkeypatch.undo()
    explicit = run(*args, "--output", tmp_path / "tiled.png", "--tile", "128")
    assert explicit.exit_code == 0, explicit.output
    np.testing.assert_array_equal(cv2.imread(str(tmp_path / "auto.png")),
                                  cv2.imread(str(tmp_path / "tiled.png")))


def test_deblur_flips_and_multiscale_match_the_api(tmp_path):
    import torch

    from dualpixel.api import deblur
    from dualpixel.io.images import read_rgb

    # Not the residual fixture: that one starts at the mean of the views, which flips anyway.
    torch.manual_seed(0)
    checkpoint = tmp_path / "plain.safetensors"
    save_model(checkpoint, build_model("rdpd", width=0.125))
    rng = np.random.default_rng(1)
    for name in ("l", "r"):
        cv2.imwrite(str(tmp_path / f"{name}.png"), rng.integers(0, 65535, (32, 48, 3), np.uint16))
    outputs = {}
    for flag in ("", "--flips", "--multiscale"):
        out = tmp_path / f"out{flag}.png"
        result = run("deblur", "--left", tmp_path / "l.png", "--right", tmp_path / "r.png",
                     "--output", out, "--checkpoint", checkpoint, "--device", "cpu",
                     *([flag] if flag else []))
        assert result.exit_code == 0, result.output
        outputs[flag] = read_rgb(out)
    left, right = read_rgb(tmp_path / "l.png"), read_rgb(tmp_path / "r.png")
    for flag, option in (("--flips", "flips"), ("--multiscale", "multiscale")):
        expected = deblur(left, right, model=checkpoint, device="cpu", **{option: True})
        assert np.abs(outputs[flag] - expected).max() <= 1 / 65535 + 1e-6  # 16-bit rounding
        assert np.abs(outputs[flag] - outputs[""]).max() > 1e-3


def test_deblur_sequence_folder_and_dataset(checkpoint, tiny_synthetic_dataset, tmp_path):
    seq = "seq_001"
    left = tiny_synthetic_dataset / "train_l" / "source" / seq
    right = tiny_synthetic_dataset / "train_r" / "source" / seq
    result = run("deblur", "--left", left, "--right", right, "--output", tmp_path / "seq",
                 "--checkpoint", checkpoint, "--tile", "32", "--overlap", "16")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "seq").iterdir()) == sorted(
        p.name for p in left.iterdir())
    result = run("deblur", "--input", tiny_synthetic_dataset, "--split", "train",
                 "--output", tmp_path / "ds", "--checkpoint", checkpoint)
    assert result.exit_code == 0, result.output
    assert len(list((tmp_path / "ds").rglob("*.png"))) == 12


def test_eval_on_canon_folder(shared_dir, tmp_path):
    canon = shared_dir / "data" / "canon-dp-real"
    categories = tmp_path / "cats.csv"
    categories.write_text("".join(f"scene_0{k},{'indoor' if k < 4 else 'outdoor'}\n"
                                  for k in range(7)))
    result = run("eval", "--dataset", canon, "--no-model", "--categories", categories,
                 "--output", tmp_path / "report", "--figures", "1", "--no-niqe")
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())["summary"]
    assert round(summary["input"]["combined"]["psnr"], 2) == 24.80
    assert round(summary["dpdnet"]["combined"]["psnr"], 2) == 27.12
    assert summary["dpdnet"]["indoor"]["count"] == 4 and summary["dpdnet"]["outdoor"]["count"] == 3
    table = (tmp_path / "report" / "summary.md").read_text()
    assert "Indoor PSNR" in table and "| dpdnet | " in table
    csv_lines = (tmp_path / "report" / "per_image.csv").read_text().splitlines()
    assert len(csv_lines) == 1 + 7 * 2
    assert (tmp_path / "report" / "compare_scene_00.png").stat().st_size > 10_000


def test_eval_runs_the_model_on_sequences(checkpoint, tiny_synthetic_dataset, tmp_path):
    result = run("eval", "--dataset", tiny_synthetic_dataset, "--split", "train", "--checkpoint",
                 checkpoint, "--output", tmp_path / "r", "--figures", "1", "--tile", "32",
                 "--overlap", "16",
                 "--save-outputs", "--no-niqe")
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())["summary"]
    assert summary["tiny"]["combined"]["count"] == 12 and summary["tiny"]["combined"]["seconds"] > 0
    assert len(list((tmp_path / "r" / "outputs").rglob("*.png"))) == 12
    # the residual model starts as the identity: its output scores like the input
    assert summary["tiny"]["combined"]["psnr"] == pytest.approx(
        summary["input"]["combined"]["psnr"], abs=0.5)
    # synthetic data has defocus maps: PSNR by blur size, in the summaries and as a figure
    by_blur = json.loads((tmp_path / "r" / "summary.json").read_text())["by_blur"]
    assert sum(row["pixel_fraction"] for row in by_blur) == pytest.approx(1.0)
    assert {"input", "tiny"} == set(by_blur[0]["psnr"])
    for method in ("input", "tiny"):
        assert sum(row["error_share"][method] for row in by_blur) == pytest.approx(1.0)
    assert "By true |CoC| radius" in result.output
    assert (tmp_path / "r" / "by_blur.png").stat().st_size > 10_000


def test_eval_prediction_folders_and_niqe_commands(shared_dir, tmp_path):
    canon = shared_dir / "data" / "canon-dp-real"
    pred, target = tmp_path / "pred", tmp_path / "target"
    pred.mkdir(), target.mkdir()
    for k in range(2):
        (pred / f"s{k}.png").write_bytes((canon / f"scene_0{k}" / "dpdnet.png").read_bytes())
        (target / f"s{k}.png").write_bytes((canon / f"scene_0{k}" / "target.png").read_bytes())
    too_few = run("niqe", "fit", "--images", target, "--output", tmp_path / "niqe.npz")
    assert too_few.exit_code == 2 and "at least 37 sharp" in too_few.output  # 18 blocks
    for k in range(2, 7):
        (target / f"s{k}.png").write_bytes((canon / f"scene_0{k}" / "target.png").read_bytes())
    result = run("niqe", "fit", "--images", target, "--output", tmp_path / "niqe.npz")
    assert result.exit_code == 0, result.output
    for k in range(2, 7):
        (target / f"s{k}.png").unlink()
    result = run("eval", "--pred", pred, "--target", target, "--niqe-model", tmp_path / "niqe.npz",
                 "--output", tmp_path / "r")
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())["summary"]
    expected = np.mean([25.38, 28.54])
    assert summary["prediction"]["combined"]["psnr"] == pytest.approx(expected, abs=0.01)
    from dualpixel import niqe
    from dualpixel.evaluation.niqe import NIQEModel
    from dualpixel.io.images import read_rgb

    reference = NIQEModel.load(tmp_path / "niqe.npz")  # the model fitted above, scored directly
    expected_niqe = np.mean([niqe(read_rgb(path), reference)
                             for path in sorted(pred.glob("*.png"))])
    assert summary["prediction"]["combined"]["niqe"] == pytest.approx(expected_niqe, rel=1e-4)
    assert "Aligned" not in (tmp_path / "r" / "summary.md").read_text()
    # registered to their targets: DPDNet's outputs move by a fraction of a pixel
    result = run("eval", "--pred", pred, "--target", target, "--no-niqe", "--align", "affine",
                 "--output", tmp_path / "ra")
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "ra" / "summary.json").read_text())
    aligned = report["summary"]["prediction"]["combined"]["aligned_psnr"]
    assert report["align"] == "affine" and abs(aligned - expected) < 1.0
    assert "Aligned PSNR" in (tmp_path / "ra" / "summary.md").read_text()
    assert "aligned_psnr" in (tmp_path / "ra" / "per_image.csv").read_text().splitlines()[0]
    score = run("niqe", "score", pred / "s0.png", "--model", tmp_path / "niqe.npz")
    assert score.exit_code == 0 and "s0.png" in score.output
    (pred / "s1.png").unlink()
    bad = run("eval", "--pred", pred, "--target", target, "--output", tmp_path / "r2")
    assert bad.exit_code == 1 and "prediction missing" in bad.output


def test_export_command(checkpoint, tmp_path):
    """As a user runs it (its own process: torch's exporter logs to the process's stderr);
    issue #73: it printed four notes about torchvision, which nothing here uses."""
    import subprocess
    import sys

    pytest.importorskip("onnxruntime")
    result = subprocess.run([sys.executable, "-m", "dualpixel", "export", "--checkpoint",
                             str(checkpoint), "--output", str(tmp_path / "m.onnx"), "--size",
                             "48x32", "--step"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "m.onnx").stat().st_size > 1000
    assert "torchvision" not in result.stdout + result.stderr and "wrote" in result.stdout


def test_export_at_a_size_that_cannot_fit_is_refused_before_tracing(checkpoint, tmp_path,
                                                                     monkeypatch):
    import dualpixel.memory

    monkeypatch.setattr(dualpixel.memory, "available_memory", lambda: 8 * 1024**3)
    result = run("export", "--checkpoint", checkpoint, "--output", tmp_path / "m.onnx",
                 "--size", "16384x16384")
    assert result.exit_code == 2, result.output
    assert "exporting at 16384x16384 needs about" in result.output
    assert "8.0 GiB is available" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "m.onnx").exists()


def test_deblur_never_overwrites_its_inputs(checkpoint, tiny_synthetic_dataset, tmp_path):
    """Issue #34: an output that is an input, or a folder holding one, is refused before any
    work (symlinks resolved); one-frame sequences with repeated frame names keep apart."""
    rng = np.random.default_rng(1)
    for name in ("l", "r"):
        cv2.imwrite(str(tmp_path / f"{name}.png"), rng.integers(0, 255, (32, 48, 3), np.uint8))
    before = (tmp_path / "l.png").read_bytes()
    (tmp_path / "link.png").symlink_to(tmp_path / "l.png")
    for output in (tmp_path / "l.png", tmp_path / "link.png"):
        result = run("deblur", "--left", tmp_path / "l.png", "--right", tmp_path / "r.png",
                     "--output", output, "--checkpoint", checkpoint)
        assert result.exit_code == 1 and "is the input" in result.output, result.output
    assert (tmp_path / "l.png").read_bytes() == before
    left = tiny_synthetic_dataset / "train_l" / "source" / "seq_001"
    right = tiny_synthetic_dataset / "train_r" / "source" / "seq_001"
    for output in (left, tiny_synthetic_dataset):
        result = run("deblur", "--left", left, "--right", right, "--output", output,
                     "--checkpoint", checkpoint)
        assert result.exit_code == 1 and "holds the input" in result.output, result.output
    result = run("deblur", "--input", tiny_synthetic_dataset, "--split", "train", "--output",
                 tiny_synthetic_dataset, "--checkpoint", checkpoint)
    assert result.exit_code == 1 and "holds the input" in result.output
    # one-frame sequences whose frames share a name go into a folder each
    one_frame = tmp_path / "one"
    for seq in ("seq_001", "seq_002"):
        for role in ("train_l", "train_r", "train_c"):
            folder = one_frame / role / "source" / seq
            folder.mkdir(parents=True)
            cv2.imwrite(str(folder / "frame_0000.png"),
                        rng.integers(0, 255, (32, 48, 3), np.uint8))
    result = run("deblur", "--input", one_frame, "--split", "train", "--output",
                 tmp_path / "out", "--checkpoint", checkpoint)
    assert result.exit_code == 0, result.output
    assert sorted(str(p.relative_to(tmp_path / "out")) for p in
                  (tmp_path / "out").rglob("*.png")) == ["seq_001/frame_0000.png",
                                                         "seq_002/frame_0000.png"]


def test_eval_names_a_runs_best_checkpoint_by_its_run(checkpoint, tiny_synthetic_dataset,
                                                      tmp_path):
    """Issue #73: `eval --checkpoint runs/x/best.safetensors` named its row "best"."""
    import shutil

    best = tmp_path / "runs" / "photo-run" / "best.safetensors"
    best.parent.mkdir(parents=True)
    shutil.copy(checkpoint, best)
    result = run("eval", "--dataset", tiny_synthetic_dataset, "--split", "train", "--checkpoint",
                 best, "--output", tmp_path / "r", "--no-niqe")
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())["summary"]
    assert set(summary) == {"input", "photo-run-best"}


def test_synth_help_says_what_the_shipped_settings_are():
    """Issue #73: `synth --help` named the Pixel 4 PSF shapes where dataset.json records the
    broad bank."""
    from dualpixel.synthesis.dataset import SYNTH_SETTINGS

    shipped = SYNTH_SETTINGS["shipped"]
    text = " ".join(run("synth", "--help").output.split())
    assert f"the {shipped['psf_bank']} PSF bank" in text and "Pixel 4 PSF shapes" not in text
    assert all(profile in text for profile in shipped["lens_sets"])
