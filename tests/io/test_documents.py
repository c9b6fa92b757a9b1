"""Issue #34: malformed configs, recipes, camera files and dataset descriptions are refused with
the file named, never a traceback (a binary --config, a list or truncated dataset.json)."""

from __future__ import annotations

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
