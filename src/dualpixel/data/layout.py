"""Finding DP examples in the DPDD folder layout (Abuolaim & Brown 2020), real or synthetic.

Real pairs (one image per name)::

    {split}_c/source/NAME.png  {split}_l/source/NAME.png  {split}_r/source/NAME.png
    {split}_c/target/NAME.png

Synthetic sequences, as ``dualpixel synth`` writes them: the same folders with one subfolder
``seq_NNN`` per sequence holding its frames. Either way each example is a :class:`DPSequence`
(a real pair is a sequence of one frame). 8- and 16-bit PNG/TIFF are accepted.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualpixel.errors import InputFileError
from dualpixel.io.documents import read_mapping
from dualpixel.io.dpdd import list_files, role_folder
from dualpixel.io.images import IMAGE_SUFFIXES, image_size, read_rgb

__all__ = [
    "DPFramePaths",
    "DPSequence",
    "discover_any",
    "discover_dp_dataset",
    "discover_scene_folders",
    "image_files",
    "read_frame",
]


@dataclass(frozen=True)
class DPFramePaths:
    """The files of one DP frame; ``target`` and ``combined`` may be absent (inference),
    ``defocus`` (signed CoC radius map, ``.npy``) is there for synthetic data only."""

    left: Path
    right: Path
    combined: Path | None = None
    target: Path | None = None
    defocus: Path | None = None


@dataclass(frozen=True)
class DPSequence:
    """An ordered list of frames of one size (a real image pair is a sequence of length 1)."""

    name: str
    frames: tuple[DPFramePaths, ...]
    height: int
    width: int


def read_frame(paths: DPFramePaths) -> dict[str, np.ndarray]:
    """Decode a frame's views (and target, where present) as float32 ``(H, W, 3)`` in [0, 1]."""
    frame = {"left": read_rgb(paths.left), "right": read_rgb(paths.right)}
    if paths.target is not None:
        frame["target"] = read_rgb(paths.target)
    return frame


def image_files(folder: Path) -> dict[str, Path]:
    """Images directly in ``folder`` by stem, in name order (hidden and partial files skipped)."""
    return list_files(folder, IMAGE_SUFFIXES)


def _check_sizes(frames: list[DPFramePaths]) -> tuple[int, int]:
    """The common (H, W) of all views and targets of ``frames``; an error names the odd file."""
    first = frames[0].left
    height, width = image_size(first)
    for frame in frames:
        for path in (frame.left, frame.right, frame.target):
            if path is not None and (size := image_size(path)) != (height, width):
                raise InputFileError(
                    path, f"size {size[1]}x{size[0]} differs from {first.name} ({width}x{height})"
                )
    return height, width


def _frames(
    left_dir: Path, right_dir: Path, combined_dir: Path, target_dir: Path | None,
    defocus_dir: Path | None = None,
) -> list[DPFramePaths]:
    lefts = image_files(left_dir)
    if not lefts:
        raise InputFileError(left_dir, "no images found")
    rights = image_files(right_dir)
    combined = image_files(combined_dir) if combined_dir.is_dir() else {}
    targets = image_files(target_dir) if target_dir is not None and target_dir.is_dir() else {}
    defocus = (list_files(defocus_dir, (".npy",))
               if defocus_dir is not None and defocus_dir.is_dir() else {})
    frames = []
    for stem, left in lefts.items():
        if stem not in rights:
            raise InputFileError(right_dir, f"right view of {left.name} is missing")
        if target_dir is not None and stem not in targets:
            raise InputFileError(target_dir, f"target of {left.name} is missing")
        frames.append(DPFramePaths(left, rights[stem], combined.get(stem), targets.get(stem),
                                   defocus.get(stem)))
    return frames


def _check_finished(description: Path) -> None:
    """Refuse a dataset ``dualpixel synth`` has not finished (its frames may be half-written)."""
    if not description.is_file():
        return  # a real dataset (DPDD) has no description
    status = read_mapping(description, "dataset description")
    if status.get("status", "complete") != "complete":
        raise InputFileError(
            description, f"says the dataset is unfinished ({status.get('frames_done', '?')}/"
            f"{status.get('frames_total', '?')} frames); rerun `dualpixel synth` with the same "
            "settings to finish it"
        )


def discover_dp_dataset(
    root: str | Path, split: str = "train", *, require_target: bool = True,
    allow_incomplete: bool = False,
) -> list[DPSequence]:
    """All examples of ``split`` under a DPDD-layout ``root`` (real pairs or ``seq_NNN`` folders).

    Raises :class:`InputFileError` naming the folder or file for a missing view folder, a missing
    view or target, images of different sizes, or no images at all, and for a synthetic dataset
    whose ``dataset.json`` says it is unfinished (unless ``allow_incomplete``).
    """
    root = Path(root)
    if not allow_incomplete:
        _check_finished(root / "dataset.json")
    left_root, right_root, combined_root, target_root, defocus_root = (
        role_folder(root, split, role)
        for role in ("left", "right", "combined", "target", "defocus"))
    for folder in (left_root, right_root) + ((target_root,) if require_target else ()):
        if not folder.is_dir():
            raise InputFileError(folder, "folder missing (expected the DPDD layout)")
    target = target_root if target_root.is_dir() else None
    sequence_dirs = sorted(
        p for p in left_root.iterdir() if p.is_dir() and p.name.startswith("seq")
    )
    if sequence_dirs:
        sequences = []
        for folder in sequence_dirs:
            frames = _frames(
                folder, right_root / folder.name, combined_root / folder.name,
                target / folder.name if target else None, defocus_root / folder.name,
            )
            sequences.append(DPSequence(folder.name, tuple(frames), *_check_sizes(frames)))
        return sequences
    frames = _frames(left_root, right_root, combined_root, target, defocus_root)
    return [DPSequence(f.left.stem, (f,), *_check_sizes([f])) for f in frames]


#: File stems of a scene folder (``scene_NN/view0.png`` ...) with the role they play.
SCENE_ROLES = {
    "left": ("left", "view0"), "right": ("right", "view1"),
    "combined": ("input", "combined"), "target": ("target", "gt"),
}


def discover_scene_folders(
    root: str | Path, *, require_target: bool = True,
) -> tuple[list[DPSequence], dict[str, dict[str, Path]]]:
    """Examples stored one folder per scene (e.g. ``../shared/data/canon-dp-real``).

    Each subfolder holds ``view0``/``left``, ``view1``/``right``, ``input``/``combined`` and
    ``target`` images (``target`` optional unless ``require_target``); any other image in it
    (e.g. ``dpdnet.png``) is another method's output, returned as ``{scene: {method: path}}``.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputFileError(root, "folder not found")
    sequences, others = [], {}
    for folder in sorted(p for p in root.iterdir() if p.is_dir()):
        images = image_files(folder)
        roles: dict[str, Path] = {}
        for role, stems in SCENE_ROLES.items():
            found = [images[s] for s in stems if s in images]
            if found:
                roles[role] = found[0]
        if "left" not in roles and "right" not in roles:
            continue
        for role in ("left", "right", "target") if require_target else ("left", "right"):
            if role not in roles:
                names = " or ".join(SCENE_ROLES[role])
                raise InputFileError(folder, f"{role} image missing ({names})")
        frame = DPFramePaths(roles["left"], roles["right"], roles.get("combined"),
                             roles.get("target"))
        sequences.append(DPSequence(folder.name, (frame,), *_check_sizes([frame])))
        used = {p for p in roles.values()}
        others[folder.name] = {stem: p for stem, p in images.items() if p not in used}
    if not sequences:
        raise InputFileError(root, "no scene folders with left/right views found")
    return sequences, others


def discover_any(
    root: str | Path, split: str | None = None, *, require_target: bool | None = None
) -> list[DPSequence]:
    """Sequences of a DPDD-layout folder (``split``, default "test" then "train", "val") or of a
    folder of scene folders (``scene/view0.png ...``, as ``../shared/data/canon-dp-real``).
    ``require_target``: None asks for targets in scene folders only."""
    root = Path(root)
    if not root.is_dir():
        raise InputFileError(root, "folder not found")
    dpdd_splits = [s for s in ("test", "train", "val") if role_folder(root, s, "left").is_dir()]
    if dpdd_splits:  # the split only means something for the DPDD layout
        return discover_dp_dataset(root, split or dpdd_splits[0],
                                   require_target=bool(require_target))
    sequences, _ = discover_scene_folders(root, require_target=require_target is not False)
    return sequences
