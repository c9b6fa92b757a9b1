"""The results tables of the README and the model card, generated from the registry and the
results CSVs, never typed (as torchvision generates its weights table).

Sources: ``registry.json`` (:mod:`dualpixel.weights`: tags, aliases, metrics, output settings),
``docs/results/TAG.csv`` (per image of every evaluation a tag's recipe ran, written by
``dualpixel release``), ``docs/results/target-free.csv`` (``dualpixel check-model`` on the
real pairs without targets, each shipped model with its own settings) and
``docs/results/outside-family.csv`` (per image, each shipped model on synthetic cameras none was
trained on: ``experiments/scripts/out_of_family.sh``). Each table sits in a
document between ``<!-- generated: NAME -->`` and ``<!-- end generated: NAME -->``;
``python -m dualpixel.evaluation.tables`` rewrites them, ``--check`` only compares.
"""

from __future__ import annotations

import argparse
import csv
import math
import re
import sys
from collections import defaultdict
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from dualpixel.errors import DualPixelError, InputFileError

__all__ = ["DOCUMENTS", "dev_scene_table", "held_out_table", "method_label",
           "outside_family_table", "render_tables", "target_free_table", "update_documents",
           "weights_table"]

#: The dev scenes' evaluations and their column titles.
DEV_SETS = {"canon-dp-real": "Canon 840x512", "canon-dp-real-hd": "Canon 1620x980"}
#: Published references on the dev scenes (PSNR / SSIM, ``../shared/data/canon-dp-real*``).
DEV_REFERENCES = {
    "blurred input": {"canon-dp-real": (24.80, 0.670), "canon-dp-real-hd": (24.69, 0.751)},
    "published DPDNet (trained on real Canon pairs)": {
        "canon-dp-real": (27.12, 0.795), "canon-dp-real-hd": (27.19, 0.865)},
}
#: Which tables each document holds (paths relative to the repository root).
DOCUMENTS = {"README.md": ("weights",),
             "src/dualpixel/weights/MODEL_CARD.md": ("held-out", "outside-family", "dev-scenes",
                                                     "target-free")}
#: Camera groups of the target-free pairs: (label, test on the pair's name), first match wins.
PAIR_GROUPS: tuple[tuple[str, Callable[[str], bool]], ...] = (
    ("Pixel 4 (MP4)", lambda n: n.startswith("dp-real-nogt/pixel-mp4-")),
    ("Pixel 4 (GIF)", lambda n: re.fullmatch(r"dp-real-nogt/pixel-gif-0\d", n) is not None),
    ("Canon EOS R6 II", lambda n: n.startswith("dp-real-nogt/sdirt-")),
    ("other Pixel and Canon (GIF)", lambda n: n.startswith("dp-real-nogt/")),
    ("Canon dev, 840x512", lambda n: n.startswith("canon-dp-real/")),
    ("Canon dev, 1620x980", lambda n: n.startswith("canon-dp-real-hd/")),
)


def _read_csv(path: Path) -> list[dict[str, str]]:
    if not path.is_file():
        raise InputFileError(path, "results file not found")
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def _mode_words(settings: Mapping[str, Any]) -> list[str]:
    """A model's output settings as words, which are also a results method's suffixes
    (``CHECKPOINT+flips+limited+tied``)."""
    return [w for w, on in (("flips", settings.get("flips")),
                            ("limited", settings.get("overshoot") == "limited"),
                            ("tied", settings.get("brightness") == "tied")) if on]


def settings_label(settings: Mapping[str, Any]) -> str:
    """How a model runs, in words: ``flips, limited, tied`` or ``as given``."""
    return ", ".join(_mode_words(settings)) or "as given"


def _tag_label(tag: str, aliases: Mapping[str, str], default: str) -> str:
    names = [a + (", the default" if a == default else "") for a, t in aliases.items() if t == tag]
    return f"`{tag}`" + (f" ({'; '.join(names)})" if names else "")


def weights_table(weights: Mapping[str, Any], aliases: Mapping[str, str], default: str,
                  results: Mapping[str, list[dict[str, str]]] | None = None) -> str:
    """PSNR / SSIM of every shipped tag on the dev scenes as it runs (the means of its results
    CSV where it has them, else its registry metrics), beside the blurred input and the
    published DPDNet, with the settings each runs with."""
    head = "| tag | " + " | ".join(DEV_SETS.values()) + " | runs with |"
    lines = [head, "|---" * (len(DEV_SETS) + 2) + "|"]
    references = [f"| {name} | " + " | ".join(f"{p:.2f} / {s:.3f}" for p, s in
                                              (scores[k] for k in DEV_SETS)) + " | – |"
                  for name, scores in DEV_REFERENCES.items()]
    lines.append(references[0])  # the input first, the published model last
    for tag, row in weights.items():
        cells = []
        for key in DEV_SETS:
            rows = [r for r in (results or {}).get(tag, []) if r["evaluation"] == key]
            score = ({"psnr": _mean(rows, "psnr"), "ssim": _mean(rows, "ssim")} if rows
                     else row.metrics.get(key))
            cells.append(f"{score['psnr']:.2f} / {score['ssim']:.3f}" if score else "–")
        lines.append(f"| {_tag_label(tag, aliases, default)} | " + " | ".join(cells)
                     + f" | {settings_label(row.output)} |")
    return "\n".join(lines + references[1:])


def dev_scene_table(results: Mapping[str, list[dict[str, str]]],
                    labels: Mapping[str, str]) -> str:
    """Per dev scene, each tag's PSNR gain over the blurred input (dB), from its results CSV,
    at both resolutions; a mean row."""
    columns = [(tag, key) for key in DEV_SETS for tag in labels]
    gains: dict[tuple[str, str], dict[str, float]] = defaultdict(dict)
    for tag, key in columns:
        for row in results.get(tag, []):
            if row["evaluation"] == key:
                gains[tag, key][row["image"]] = float(row["psnr"]) - float(row["input_psnr"])
    columns = [c for c in columns if gains[c]]
    scenes = sorted({s for c in columns for s in gains[c]})
    head = "| scene | " + " | ".join(f"{DEV_SETS[k].split()[1]}: {labels[t]}"
                                      for t, k in columns) + " |"
    lines = [head, "|---" * (len(columns) + 1) + "|"]
    for scene in scenes:
        lines.append(f"| {scene.removeprefix('scene_')} | " + " | ".join(
            f"{gains[c][scene]:+.2f}" if scene in gains[c] else "–" for c in columns) + " |")
    lines.append("| mean | " + " | ".join(
        f"**{sum(gains[c].values()) / len(gains[c]):+.2f}**" for c in columns) + " |")
    return "\n".join(lines)


def held_out_table(results: Mapping[str, list[dict[str, str]]],
                   labels: Mapping[str, str]) -> str:
    """Per held-out synthetic evaluation (every one of a tag's results CSV but the dev scenes),
    each tag's mean PSNR and its gain over the blurred input (dB)."""
    scores: dict[str, dict[str, list[tuple[float, float]]]] = defaultdict(
        lambda: defaultdict(list))
    for tag in labels:
        for row in results.get(tag, []):
            if row["evaluation"] not in DEV_SETS:
                scores[row["evaluation"]][tag].append((float(row["psnr"]),
                                                       float(row["input_psnr"])))
    tags = [t for t in labels if any(t in by_tag for by_tag in scores.values())]
    lines = ["| held-out frames | images | " + " | ".join(f"{labels[t]}: PSNR (gain)"
                                                          for t in tags) + " |",
             "|---" * (len(tags) + 2) + "|"]
    for evaluation, by_tag in scores.items():
        cells = []
        for tag in tags:
            pairs = by_tag.get(tag)
            if not pairs:
                cells.append("–")
                continue
            model = sum(p for p, _ in pairs) / len(pairs)
            given = sum(i for _, i in pairs) / len(pairs)
            cells.append(f"{model:.2f} ({model - given:+.2f})")
        count = max(len(v) for v in by_tag.values())
        lines.append(f"| {evaluation} | {count} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def outside_family_table(rows: Iterable[dict[str, str]], labels: Mapping[str, str]) -> str:
    """A row per method, a column per synthetic camera outside the training family (an
    ``evaluation`` of ``outside-family.csv``, with its number of images): the method's mean
    PSNR gain over the blurred input (dB) and how many of its images lose against their input."""
    gains: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for row in rows:
        if row["method"] in labels:
            gains[row["method"]][row["evaluation"]].append(
                float(row["psnr"]) - float(row["input_psnr"]))
    cameras: dict[str, int] = {}
    for by_camera in gains.values():
        for camera, values in by_camera.items():
            cameras[camera] = max(cameras.get(camera, 0), len(values))
    lines = ["| model | " + " | ".join(f"{c} ({n})" for c, n in cameras.items()) + " |",
             "|---" * (len(cameras) + 1) + "|"]
    for method in (m for m in labels if m in gains):
        cells = []
        for camera in cameras:
            values = gains[method].get(camera)
            if not values:
                cells.append("–")
                continue
            losing = sum(v < 0 for v in values)
            cells.append(f"{sum(values) / len(values):+.2f}"
                         + (f" ({losing} lose)" if losing else ""))
        lines.append(f"| {labels[method]} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _mean(rows: list[dict[str, str]], key: str) -> float:
    values = [float(r[key]) for r in rows if r[key] not in ("", "nan")
              and not math.isnan(float(r[key]))]
    return sum(values) / len(values) if values else math.nan


def target_free_table(rows: Iterable[dict[str, str]], labels: Mapping[str, str]) -> str:
    """Means per camera group of ``check-model``'s results for the methods in ``labels``:
    brightness change over the frame (and the largest, %), local shift (%), overshoot and
    in-focus change (levels of 255), sharpness gained."""
    groups: dict[tuple[str, str], list[dict[str, str]]] = defaultdict(list)
    for row in rows:
        if row["method"] not in labels:
            continue
        group = next(label for label, test in PAIR_GROUPS if test(row["pair"]))
        groups[group, row["method"]].append(row)
    lines = ["| pairs | model | brightness % | local % | overshoot | in-focus | sharpness |",
             "|---|---|---|---|---|---|---|"]
    for group, _ in PAIR_GROUPS:
        for k, method in enumerate(m for m in labels if groups.get((group, m))):
            chosen = groups[group, method]
            change = [100 * float(r["brightness_change"]) for r in chosen]
            largest = max(change, key=abs)
            name = f"{len(chosen)} {group}" if k == 0 else ""
            lines.append(
                f"| {name} | {labels[method]} | {sum(change) / len(change):+.2f} "
                f"({largest:+.2f}) | {100 * _mean(chosen, 'local_brightness'):.2f} | "
                f"{_mean(chosen, 'overshoot'):.2f} | {_mean(chosen, 'in_focus_change'):.2f} | "
                f"{_mean(chosen, 'sharpness_gain'):.2f} |")
    return "\n".join(lines)


def _method_parts(method: str) -> tuple[str, list[str]]:
    """A results method (``CHECKPOINT+flips+limited+tied``) as its checkpoint's tag (an alias
    resolved) and its mode words."""
    from dualpixel.weights import ALIASES

    base, *modes = method.split("+")
    return ALIASES.get(base, base), modes


def method_label(method: str) -> str | None:
    """A results method (``CHECKPOINT+flips+limited+tied``) as a table label, when its
    checkpoint is a shipped alias or tag (None otherwise)."""
    from dualpixel.weights import WEIGHTS

    tag, modes = _method_parts(method)
    if tag not in WEIGHTS:
        return None
    settings = {"flips": "flips" in modes, "overshoot": "limited" if "limited" in modes else "",
                "brightness": "tied" if "tied" in modes else ""}
    return f"`{tag}` ({settings_label(settings)})"


def render_tables(root: str | Path) -> dict[str, str]:
    """Every generated table by name, from ``root``'s ``docs/results`` and the registry."""
    from dualpixel.weights import ALIASES, DEFAULT_CHECKPOINT, WEIGHTS

    results_dir = Path(root) / "docs" / "results"
    default = ALIASES.get(DEFAULT_CHECKPOINT, DEFAULT_CHECKPOINT)
    tags = sorted(WEIGHTS, key=lambda tag: tag != default)  # the default first
    results = {tag: _read_csv(results_dir / f"{tag}.csv") for tag in tags
               if (results_dir / f"{tag}.csv").is_file()}
    target_free = _read_csv(results_dir / "target-free.csv")
    outside = _read_csv(results_dir / "outside-family.csv")
    return {
        "weights": weights_table({tag: WEIGHTS[tag] for tag in tags}, ALIASES,
                                 DEFAULT_CHECKPOINT, results),
        "dev-scenes": dev_scene_table(results, {tag: f"`{tag}`" for tag in tags}),
        "held-out": held_out_table(results, {tag: f"`{tag}`" for tag in tags}),
        "outside-family": outside_family_table(outside, _shipped_methods(outside, default)),
        "target-free": target_free_table(target_free, _shipped_methods(target_free, default)),
    }


def _shipped_methods(rows: Iterable[dict[str, str]], default: str) -> dict[str, str]:
    """The results methods of ``rows`` that are a shipped tag run with its own output settings,
    each with its table label; the default's first."""
    from dualpixel.weights import WEIGHTS

    methods: dict[str, str] = {}
    for row in sorted(rows, key=lambda r: _method_parts(r["method"])[0] != default):
        label = method_label(row["method"])
        tag, modes = _method_parts(row["method"])
        if label is not None and set(modes) == set(_mode_words(WEIGHTS[tag].output)):
            methods.setdefault(row["method"], label)
    return methods


def _replace(text: str, name: str, table: str, path: Path) -> str:
    start, end = f"<!-- generated: {name} -->", f"<!-- end generated: {name} -->"
    if text.count(start) != 1 or text.count(end) != 1:
        raise InputFileError(path, f"needs one '{start}' and one '{end}'")
    before, rest = text.split(start)
    _, after = rest.split(end)
    return f"{before}{start}\n{table}\n{end}{after}"


def update_documents(root: str | Path, *, check: bool = False) -> list[Path]:
    """Rewrite the generated tables in :data:`DOCUMENTS` under ``root``; the documents that
    changed (``check=True``: that would change, nothing written)."""
    tables = render_tables(root)
    changed = []
    for name, parts in DOCUMENTS.items():
        path = Path(root) / name
        text = path.read_text(encoding="utf-8")
        new = text
        for part in parts:
            new = _replace(new, part, tables[part], path)
        if new != text:
            changed.append(path)
            if not check:
                path.write_text(new, encoding="utf-8")
    return changed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", default=".", help="the repository root")
    parser.add_argument("--check", action="store_true",
                        help="exit 1 when a document's tables differ from the generated ones")
    args = parser.parse_args(argv)
    try:
        changed = update_documents(args.root, check=args.check)
    except DualPixelError as error:
        print(f"Error: {error}", file=sys.stderr)
        return 2
    for path in changed:
        print(f"{'differs' if args.check else 'updated'}: {path}")
    return 1 if args.check and changed else 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
