"""Issue #34: malformed configs, recipes, camera files and dataset descriptions are refused with
the file named, never a traceback (a binary --config, a list or truncated dataset.json)."""

from __future__ import annotations

import json
import shutil

import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.errors import InputFileError
from dualpixel.io.documents import read_mapping

BINARY = bytes(range(128, 256)) * 3


@pytest.mark.parametrize("content, problem", [
    (BINARY, "is not a text file"),
    (b'{"status": "complete", "frames"', "is not valid JSON"),
    (b"[1, 2]", "got list"),
    (b"", "is not valid JSON"),
])
def test_read_mapping_names_the_file_and_the_problem(tmp_path, content, problem):
    path = tmp_path / "dataset.json"
    path.write_bytes(content)
    with pytest.raises(InputFileError, match=rf"dataset\.json: .*{problem}"):
        read_mapping(path, "dataset description")


def test_commands_refuse_malformed_documents(tmp_path, tiny_synthetic_dataset):
    runner = CliRunner()
    (tmp_path / "bin.yaml").write_bytes(BINARY)
    result = runner.invoke(cli, ["train", "--config", str(tmp_path / "bin.yaml"), "--output",
                                 str(tmp_path / "run")])
    assert result.exit_code == 1 and "bin.yaml: is not a text file" in result.output
    result = runner.invoke(cli, ["reproduce", str(tmp_path / "bin.yaml"), "--output",
                                 str(tmp_path / "r"), "--dry-run"])
    assert result.exit_code == 1 and "bin.yaml: is not a text file" in result.output
    (tmp_path / "tabs.yaml").write_text("epochs: [1,\n\tb")
    result = runner.invoke(cli, ["train", "--config", str(tmp_path / "tabs.yaml"), "--output",
                                 str(tmp_path / "run")])
    assert result.exit_code == 1 and "tabs.yaml: is not valid YAML" in result.output
    for content in (b"[1, 2]", b'{"status": "comp'):
        data = tmp_path / "data"
        shutil.rmtree(data, ignore_errors=True)
        shutil.copytree(tiny_synthetic_dataset, data)
        (data / "dataset.json").write_bytes(content)
        result = runner.invoke(cli, ["stats", str(data), "--split", "train"])
        assert result.exit_code == 1 and "dataset.json" in result.output, result.output
        assert "Traceback" not in result.output
    (tmp_path / "camera.json").write_bytes(BINARY)
    result = runner.invoke(cli, ["synth", "--input", str(tmp_path), "--output",
                                 str(tmp_path.parent / f"{tmp_path.name}-s"), "--camera",
                                 str(tmp_path / "camera.json")])
    assert result.exit_code != 0 and "camera.json" in result.output, result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize("line", ['[1, 2]', '{"key": 5, "outputs": {}}', '{"key": "a"}'])
def test_manifest_lines_that_are_not_frame_records_are_refused(tmp_path, line):
    from dualpixel.io.dpdd import read_manifest

    manifest = tmp_path / "manifest.jsonl"
    good = '{"key": "train/seq_000/frame_0000", "outputs": {"left": "x.png"}}'
    manifest.write_text(f"{good}\n{line}\n" + '{"key": "tr')  # and a torn last append
    with pytest.raises(InputFileError, match=r"manifest\.jsonl: line 2 is not a frame record"):
        read_manifest(manifest)
    manifest.write_text(f"{good}\n" + '{"key": "tr')
    assert list(read_manifest(manifest)) == ["train/seq_000/frame_0000"]


# Issue #72: numbers without bounds. Every document is read by one reader that refuses
# non-finite numbers and integers beyond 63 bits (naming the key), and the readers of typed keys
# refuse a flag where a number belongs.

@pytest.mark.parametrize("text, problem", [
    ('{"psf": {"alpha": Infinity}}', r"psf\.alpha is an infinity; numbers must be finite"),
    ('{"ratios": [0.5, NaN]}', r"ratios\[1\] is NaN"),
    ('{"width": 1' + "0" * 400 + "}", "width is an integer of 401 digits"),
    ('{"width": -1e999}', "width is an infinity"),
])
def test_documents_refuse_numbers_without_bounds(tmp_path, text, problem):
    path = tmp_path / "camera.json"
    path.write_text(text)
    with pytest.raises(InputFileError, match=rf"camera\.json: {problem}"):
        read_mapping(path, "camera file")


def test_yaml_infinities_are_refused_like_json_ones(tmp_path):
    path = tmp_path / "config.yaml"
    path.write_text("learning_rate: .inf\nepochs: 3\n")
    with pytest.raises(InputFileError, match="learning_rate is an infinity"):
        read_mapping(path, "training config", syntax="yaml")
    path.write_text("learning_rate: 1.0e-4\nseed: 9223372036854775807\n")  # the largest seed
    assert read_mapping(path, "training config", syntax="yaml")["seed"] == 2**63 - 1


@pytest.mark.parametrize("field, value, problem", [
    ("width", True, "width must be an integer, got True"),
    ("width", 840.0, "width must be an integer, got 840.0"),
    ("width", 0, r"width must be in \[1, 65536\]"),
    ("blocks", "many", "blocks must be an integer"),
    ("noise_std", False, "noise_std must be a number, got False"),
    ("noise_std", 2.0, r"noise_std must be in \[0, 1\]"),
    ("psf", {"n": True, "alpha": 0.45, "beta": 0.2, "kappa": 0.21},
     "psf.n must be a number, got True"),
    ("disparity_ratio", [0.7, True, 1.0], r"disparity_ratio\[1\] must be a number"),
    ("coc_percentiles", {"p50": "x"}, r"coc_percentiles\.p50 must be a number"),
])
def test_camera_files_refuse_flags_and_out_of_range_numbers(tmp_path, field, value, problem):
    from dualpixel.optics.camera import load_camera

    data = json.loads(shipped_camera_text("canon-840"))
    data[field] = value
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(data))
    with pytest.raises(InputFileError, match=rf"camera\.json: bad camera field: {problem}"):
        load_camera(path)


def shipped_camera_text(name: str) -> str:
    from dualpixel.cameras import shipped_camera

    return shipped_camera(name).read_text()


@pytest.fixture(scope="module")
def photo_scene(tmp_path_factory):
    """One 64x48 "photo" layout scene (it writes a focus distance)."""
    scenes = tmp_path_factory.mktemp("scenes") / "scenes"
    result = CliRunner().invoke(cli, ["scenes", "-o", str(scenes), "--sequences", "1",
                                      "--frames", "1", "--size", "64x48", "--layout", "photo"])
    assert result.exit_code == 0, result.output
    return scenes


def test_synth_names_a_bad_camera_file(tmp_path, photo_scene):
    data = json.loads(shipped_camera_text("canon-840"))
    data["width"] = True
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(data))
    result = CliRunner().invoke(cli, ["synth", "--input", str(photo_scene), "-o",
                                      str(tmp_path / "dp"), "--camera", str(path)])
    assert result.exit_code == 1, result.output
    assert "camera.json: bad camera field: width must be an integer" in result.output
    assert not (tmp_path / "dp").exists() or not any((tmp_path / "dp").iterdir())


@pytest.mark.parametrize("value, problem", [
    ("true", "must be a number, got True"),
    ("-2.0", "must be in"),
    ("NaN", "is NaN"),
])
def test_a_scene_files_bad_focus_distance_names_the_file(tmp_path, photo_scene, value, problem):
    scenes = tmp_path / "scenes"
    shutil.copytree(photo_scene, scenes)
    (scenes / "seq_000" / "scene.json").write_text(f'{{"focus_distance": {value}}}')
    result = CliRunner().invoke(cli, ["synth", "--input", str(scenes), "-o", str(tmp_path / "dp")])
    assert result.exit_code == 1, result.output
    assert "scene.json: " in result.output and problem in result.output, result.output


def test_line_based_files_that_are_binary_are_named(tmp_path, tiny_synthetic_dataset):
    """Found probing (issue #72): a binary --categories file was a UnicodeDecodeError traceback;
    category lists, frame manifests and run histories are read by one text reader."""
    from dualpixel.io.documents import read_text_file
    from dualpixel.io.dpdd import read_manifest

    binary = tmp_path / "cats.csv"
    binary.write_bytes(BINARY)
    result = CliRunner().invoke(cli, ["eval", "--dataset", str(tiny_synthetic_dataset),
                                      "--split", "train", "--no-model", "--categories",
                                      str(binary), "-o", str(tmp_path / "r"), "--no-niqe"])
    assert result.exit_code == 1, result.output
    assert "cats.csv: is not a text file (expected a category list)" in result.output
    manifest = tmp_path / "manifest.jsonl"
    manifest.write_bytes(BINARY)
    with pytest.raises(InputFileError, match=r"manifest\.jsonl: is not a text file"):
        read_manifest(manifest)
    with pytest.raises(InputFileError, match=r"nothing\.txt: training history not found"):
        read_text_file(tmp_path / "nothing.txt", "training history")
