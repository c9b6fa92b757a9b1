import numpy as np
from click.testing import CliRunner
from PIL import Image

from dualpixel.cli.main import cli


def test_every_command_has_help():
    runner = CliRunner()
    result = runner.invoke(cli, ["--help"])
    assert result.exit_code == 0
    for name in cli.commands:
        sub = runner.invoke(cli, [name, "--help"])
        assert sub.exit_code == 0, name
        assert "Usage" in sub.output


def test_psf_command_writes_figure_and_arrays(tmp_path):
    out, arrays = tmp_path / "fig.png", tmp_path / "k.npz"
    result = CliRunner().invoke(
        cli, ["psf", "--output", str(out), "--radii", "-8,4", "--save", str(arrays)]
    )
    assert result.exit_code == 0, result.output
    with Image.open(out) as img:
        assert img.format == "PNG" and img.size[0] > 400
    data = np.load(arrays)
    assert data["left"].shape == data["right"].shape == data["combined"].shape
    assert data["left"].shape[0] == 2
    np.testing.assert_allclose(data["left"].sum(axis=(1, 2)), 0.5, atol=1e-5)
    np.testing.assert_allclose(data["right"], data["left"][:, :, ::-1])
    assert not list(tmp_path.glob(".*"))


def test_psf_command_rejects_bad_parameters(tmp_path):
    result = CliRunner().invoke(cli, ["psf", "--output", str(tmp_path / "f.png"), "--beta", "0"])
    assert result.exit_code == 2
    assert "beta must be in (0, 1]" in result.output
    assert not (tmp_path / "f.png").exists()
