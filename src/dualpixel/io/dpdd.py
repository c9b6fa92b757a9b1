"""The DPDD folder layout, described once: the dataset writer, the readers and the commands all
use these paths (Abuolaim & Brown's DPDD, extended with ``seq_NNN`` sequences and defocus maps).

    {split}_l/source/[seq_NNN/]NAME.png    left view
    {split}_r/source/[seq_NNN/]NAME.png    right view
    {split}_c/source/[seq_NNN/]NAME.png    combined (blurred) image
    {split}_c/target/[seq_NNN/]NAME.png    sharp target
    {split}_c/defocus/[seq_NNN/]NAME.npy   signed CoC radius in pixels (synthetic data)
    manifest.jsonl, dataset.json           written by ``dualpixel synth``
"""

from __future__ import annotations

import json
from pathlib import Path

from dualpixel.errors import InputFileError
from dualpixel.io.documents import read_text_file
from dualpixel.io.images import IMAGE_SUFFIXES
from dualpixel.io.paths import broken_link, check_plain_name

__all__ = ["ROLES", "frame_paths", "list_files", "read_manifest", "role_folder"]

#: role -> (view folder suffix, subfolder)
ROLES: dict[str, tuple[str, str]] = {
    "left": ("l", "source"),
    "right": ("r", "source"),
    "combined": ("c", "source"),
    "target": ("c", "target"),
    "defocus": ("c", "defocus"),
}


def role_folder(root: str | Path, split: str, role: str) -> Path:
    """The folder of one role (``left``, ``right``, ``combined``, ``target``, ``defocus``);
    ``split`` must be a plain name (``--split ../x`` would leave ``root``)."""
    check_plain_name(split, "split")
    view, sub = ROLES[role]
    return Path(root) / f"{split}_{view}" / sub


def frame_paths(root: str | Path, split: str, sequence: str | None, name: str,
                suffix: str = ".png") -> dict[str, Path]:
    """Every file of one frame (``sequence`` None for DPDD's flat pairs); defocus is ``.npy``."""
    paths = {}
    for role in ROLES:
        folder = role_folder(root, split, role)
        if sequence is not None:
            folder = folder / sequence
        paths[role] = folder / f"{name}{'.npy' if role == 'defocus' else suffix}"
    return paths


def list_files(folder: str | Path, suffixes: tuple[str, ...] = IMAGE_SUFFIXES) -> dict[str, Path]:
    """Files directly in ``folder`` with one of ``suffixes``, by stem, in name order (hidden and
    partial files skipped); a link among them that leads nowhere is an error naming it."""
    files = {}
    for path in sorted(Path(folder).iterdir()):
        if path.suffix.lower() not in suffixes or path.name.startswith("."):
            continue
        problem = broken_link(path)
        if problem:
            raise InputFileError(path, problem)
        if path.is_file():
            files[path.stem] = path
    return files


def read_manifest(path: str | Path) -> dict[str, dict]:
    """Records of finished frames by key. A torn line (an append a kill interrupted) is
    ignored; a whole line that is not a frame record (a mapping with a string ``key`` and a
    mapping of ``outputs``) is refused, naming the file and line."""
    records: dict[str, dict] = {}
    path = Path(path)
    if path.is_file():
        for number, line in enumerate(read_text_file(path, "frame manifest").splitlines(),
                                      start=1):
            try:
                record = json.loads(line)
            except json.JSONDecodeError:
                continue
            if not (isinstance(record, dict) and isinstance(record.get("key"), str)
                    and isinstance(record.get("outputs"), dict)):
                raise InputFileError(path, f"line {number} is not a frame record (a mapping "
                                           "with a string 'key' and 'outputs')")
            records[record["key"]] = record
    return records
