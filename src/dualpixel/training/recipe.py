"""Recipes: one YAML file per model, from data to the shipped weights (``dualpixel reproduce``).

A recipe (``recipes/NAME.yaml``; after BasicSR/Restormer's one option file per published model,
with phases inside it) holds:

- ``name``, ``description``;
- ``data``: steps run in order, each ``{name, scenes: {...}}`` (:class:`SceneConfig` keys plus
  ``sequences``, ``seed`` and, for the photographic layout, ``photos``, a folder of photographs
  relative to the working directory, and ``skip_bad``) or ``{name, synth: {...}}``
  (:class:`SynthConfig` keys plus ``input``, a step's name or a folder, ``format`` and
  ``source``: ``written`` frames, or ``on-the-fly``, a source whose training crops are rendered
  as they are drawn, :mod:`dualpixel.synthesis.on_the_fly`; ``camera`` is a shipped camera's name
  (:mod:`dualpixel.cameras`) or a camera file, relative to the recipe). Step NAME writes
  ``OUTPUT/data/NAME``;
- ``train``: :class:`TrainConfig` keys shared by every phase (``architecture: rdpd-light``, a
  name of :data:`~dualpixel.models.spec.ARCHITECTURES`, stands for its model, width, residual
  and refiner keys; a phase may name another), except the machine settings
  (:data:`MACHINE_SETTINGS`: loader workers, threads, device, caches), which are the
  ``machine`` argument of :func:`reproduce` (``dualpixel reproduce`` options), never part of a
  model's recipe: they change how fast a run goes, not what it makes. In the data keys
  (``real_data``, ``synthetic_data``, ``val_data``, ``real_val_data``) a step's name stands for
  its folder; other paths are relative to the working directory;
- ``phases``: each ``{name, set: {...}, init: ...}`` names only what changes; it starts from the
  previous phase's weights (``init: previous``, the default after the first phase), from
  nothing (``init: none``, the first phase's default) or from a shipped tag
  (``init: rdpd-light.v12``, checked by its sha256; a tag that no longer ships, or another copy
  of one, comes from a file given for it: :func:`load_recipe`'s ``tag_files``, ``reproduce
  --tag-file TAG=PATH``). A phase trains in ``OUTPUT/phases/NN-NAME`` and resumes there;
- ``ship``: ``{tag, phase, doc, output}``: what the recipe ships: the tag its weights get
  (``ARCHITECTURE.vN``, see :mod:`dualpixel.weights`), the phase they come from (default the
  last), a one-line doc and the output settings the model runs with by default
  (``{brightness, overshoot, flips}``, as ``dualpixel deblur`` takes them). ``reproduce``
  exports them in float16 to ``OUTPUT/ship/TAG.safetensors`` with their provenance and metrics
  (scored with those settings); ``dualpixel release`` puts them into the package;
- ``evaluate``: ``[{name, dataset, split}]`` scored with the shipped weights (a step's name or a
  folder; a folder outside the run that is missing is skipped with a note); raw views add
  ``encoding: linear`` with ``black_level`` and ``white_level`` in the files' units, and go to
  the model as ``dualpixel eval --encoding linear`` feeds them.

``extends: BASE.yaml`` (a recipe beside this one, or a relative path such as
``../../recipes/BASE.yaml``) starts from the base: this recipe's data steps and phases replace the
base's of the same name or follow them, its ``train`` keys override the base's, and its other keys
replace the base's; a variant names only what changes.

Every step resumes: a rerun of ``reproduce`` continues where the last one stopped. Bad input
(an unknown key, a phase whose start cannot be resolved, a missing data step) is refused before
any work, naming the recipe, the phase and the key.
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dualpixel.errors import InputFileError, ParameterError, check_seed
from dualpixel.io.documents import read_mapping, read_text_file
from dualpixel.io.paths import check_plain_name
from dualpixel.names import BRIGHTNESS_MODES, OVERSHOOT_MODES, SYNTH_SOURCES, renamed_keys
from dualpixel.training.config import MACHINE_KEYS

__all__ = ["MACHINE_SETTINGS", "OUTPUT_SETTINGS", "Phase", "Recipe", "check_codecs", "load_recipe",
           "phase_done", "phase_finished", "plan_text", "reproduce"]

_TOP_KEYS = {"name", "description", "extends", "data", "train", "phases", "ship", "evaluate"}
#: How deep ``extends`` may chain.
_MAX_EXTENDS = 8
_SHIP_KEYS = {"tag", "phase", "doc", "output"}
#: Output settings a recipe's ``ship.output`` may give, with the values each takes.
OUTPUT_SETTINGS: dict[str, tuple[Any, ...]] = {
    "brightness": BRIGHTNESS_MODES, "overshoot": OVERSHOOT_MODES, "flips": (False, True)}
_DATA_KEYS = ("real_data", "synthetic_data", "val_data", "real_val_data")
#: TrainConfig keys that say how a machine runs a phase, not what it makes (the data order and
#: every draw are seeded per item, whatever the loader): given to :func:`reproduce`, never in
#: a recipe. Values: the ``dualpixel reproduce`` option of each.
MACHINE_SETTINGS = dict(zip(MACHINE_KEYS, ("--loader-workers", "--threads", "--device",
                                           "--cache", "--frame-store", "--render-on",
                                           "--checkpoint-minutes"),
                            strict=True))


@dataclass(frozen=True)
class DataStep:
    """One data step: ``kind`` is ``scenes`` or ``synth``, ``args`` its settings."""

    name: str
    kind: str
    args: dict[str, Any]


@dataclass(frozen=True)
class Phase:
    """One training phase: the config keys it changes and where its weights start."""

    name: str
    settings: dict[str, Any]
    init: str  # "none", "previous" or a shipped tag


@dataclass
class Recipe:
    """A parsed recipe (see the module docstring)."""

    path: Path
    name: str
    description: str
    data: list[DataStep]
    train: dict[str, Any]
    phases: list[Phase]
    ship: dict[str, Any]
    evaluate: list[dict[str, Any]] = field(default_factory=list)
    #: Files for tags the phases start from (tag -> path), in place of the shipped ones: where
    #: this machine keeps weights, not part of what the recipe makes (:func:`load_recipe`).
    tag_files: dict[str, str] = field(default_factory=dict)

    @property
    def start_tags(self) -> list[str]:
        """The tags the phases start from, in order: ``init: TAG``, and for an ``init:
        previous`` phase run ``--from`` without its predecessor, the tags that predecessor made
        (:func:`made_tags`)."""
        tags = []
        for i, phase in enumerate(self.phases):
            if phase.init == "previous" and i > 0:
                tags += made_tags(self, self.phases[i - 1].name)
            elif phase.init != "none":
                tags.append(phase.init)
        return list(dict.fromkeys(tags))

    def phase_folder(self, output: Path, index: int) -> Path:
        return output / "phases" / self.phases[index].name

    def phase_index(self, name: str) -> int:
        names = [p.name for p in self.phases]
        if name not in names:
            raise ParameterError(f"recipe {self.path}: no phase {name!r} (phases: "
                                 f"{', '.join(names)})")
        return names.index(name)

    @property
    def shipped_phase(self) -> str:
        """The phase whose weights ``ship`` exports: ``ship.phase``, else the last."""
        return str(self.ship.get("phase", self.phases[-1].name))

    @property
    def shipped_tag(self) -> str:
        """The tag the shipped weights get (``ship.tag``)."""
        return str(self.ship["tag"])

    @property
    def output_settings(self) -> dict[str, Any]:
        """How the shipped model runs by default (``ship.output``; unset keys: as given)."""
        return dict(self.ship.get("output") or {})


def _fail(path: Path, where: str, problem: str) -> InputFileError:
    return InputFileError(path, f"{where}: {problem}")


def _mapping(path: Path, where: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise _fail(path, where, f"expected a mapping, got {type(value).__name__}")
    return value


def _plain(path: Path, where: str, name: Any) -> str:
    """A name that becomes a folder or file name in the run folder: one plain name."""
    try:
        return check_plain_name(str(name), "name")
    except ParameterError:
        raise _fail(path, where, f"{str(name)[:80]!r} must be a plain name (letters, digits, "
                                 "'-', '_'; no '/', '..' or absolute path): it names a folder "
                                 "of the run") from None


def _ship(path: Path, raw: Any) -> dict[str, Any]:
    """The ``ship`` block, checked: a tag (``ARCHITECTURE.vN``), known keys and settings."""
    import re

    ship = dict(_mapping(path, "ship", raw or {}))
    if not ship:
        return ship
    if "name" in ship and "tag" not in ship:
        raise _fail(path, "ship", "'name' is now 'tag': the tag the weights ship under, "
                                  "e.g. rdpd-light.v13")
    unknown = sorted(set(ship) - _SHIP_KEYS)
    if unknown:
        raise _fail(path, "ship", f"unknown key(s) {', '.join(unknown)}; known: "
                                  f"{', '.join(sorted(_SHIP_KEYS))}")
    if "tag" not in ship:
        raise _fail(path, "ship", "missing key 'tag' (the tag the weights ship under)")
    _plain(path, "ship", ship["tag"])  # it names a file
    if not re.fullmatch(r"[a-z0-9][a-z0-9-]*\.v[0-9]+", str(ship["tag"])):
        raise _fail(path, "ship", f"tag {str(ship['tag'])[:80]!r} is not ARCHITECTURE.vN "
                                  "(lower-case letters, digits and '-', then .v and a number)")
    output = dict(_mapping(path, "ship output", ship.get("output") or {}))
    for key, value in output.items():
        if key not in OUTPUT_SETTINGS:
            raise _fail(path, "ship output", f"unknown key {key!r}; known: "
                                             f"{', '.join(OUTPUT_SETTINGS)}")
        if value not in OUTPUT_SETTINGS[key] or type(value) is not type(OUTPUT_SETTINGS[key][0]):
            raise _fail(path, f"ship output {key}", f"{value!r} is not one of "
                        f"{', '.join(map(str, OUTPUT_SETTINGS[key]))}")
    ship["output"] = output
    return ship


def _no_machine_settings(path: Path, where: str, settings: dict[str, Any]) -> dict[str, Any]:
    machine = [key for key in settings if key in MACHINE_SETTINGS]
    if machine:
        options = ", ".join(MACHINE_SETTINGS[key] for key in machine)
        raise _fail(path, where, f"{', '.join(machine)}: machine settings are not part of a "
                    f"model's recipe; give them to dualpixel reproduce ({options})")
    return settings


def _by_name(path: Path, where: str, items: Any) -> dict[str, Any]:
    if not isinstance(items, list):
        raise _fail(path, where, "expected a list")
    named = {}
    for k, item in enumerate(items):
        if not isinstance(item, dict) or "name" not in item:
            raise _fail(path, f"{where} entry {k + 1}", "expected a mapping with a name")
        named[str(item["name"])] = item
    return named


def _merge_by_name(path: Path, key: str, base: dict[str, Any], own: dict[str, Any]
                   ) -> list[Any]:
    """The base's ``data`` steps or ``phases`` with this recipe's replacing or following them by
    name; ``{name: NAME, drop: true}`` leaves the base's entry out."""
    merged = dict(base)
    for name, item in own.items():
        if "drop" not in item:
            merged[name] = item
        elif item != {"name": item["name"], "drop": True}:
            raise _fail(path, f"{key} entry {name}", "a dropped entry is {name, drop: true} "
                                                     "and nothing else")
        elif name not in merged:
            raise _fail(path, f"{key} entry {name}", "drop: true, but the base recipe has "
                                                     f"no {key} entry of that name")
        else:
            del merged[name]
    return list(merged.values())


def _base_path(path: Path, value: Any) -> Path:
    """The recipe that ``extends: VALUE`` of recipe ``path`` names: a ``.yaml`` file given
    relative to the recipe's folder (``BASE.yaml``, ``../../recipes/BASE.yaml``)."""
    text = str(value)
    relative = Path(text)
    if not text or relative.is_absolute() or relative.suffix not in (".yaml", ".yml"):
        raise _fail(path, "extends", f"{text[:80]!r} must be a recipe file (.yaml) given "
                                     "relative to this recipe's folder")
    base = path.parent / relative
    if not base.is_file():
        raise _fail(path, "extends", f"{text} is no recipe (looked for {base})")
    return base


def _raw_recipe(path: Path, chain: tuple[Path, ...] = ()) -> dict[str, Any]:
    """A recipe's mapping with its ``extends`` resolved: the base recipe (a path relative to
    this one's folder) with this one's ``data`` steps and ``phases`` replacing, following or
    dropping the base's by name (:func:`_merge_by_name`), its ``train`` settings over the
    base's, and its other keys replacing the base's."""
    raw = dict(read_mapping(path, "recipe", syntax="yaml"))
    unknown = sorted(set(raw) - _TOP_KEYS)
    if unknown:
        raise _fail(path, "recipe", f"unknown key(s) {', '.join(unknown)}; known: "
                                    f"{', '.join(sorted(_TOP_KEYS))}")
    if "extends" not in raw:
        return raw
    base_path = _base_path(path, raw["extends"])
    if base_path.resolve() in {p.resolve() for p in (*chain, path)} or len(chain) >= _MAX_EXTENDS:
        raise _fail(path, "extends", f"{raw['extends']} makes a cycle or a chain deeper than "
                                     f"{_MAX_EXTENDS}")
    base = _raw_recipe(base_path, (*chain, path))
    merged = {**base, **{k: v for k, v in raw.items() if k != "extends"}}
    for key in ("data", "phases"):
        if key in raw and key in base:
            merged[key] = _merge_by_name(path, key, _by_name(base_path, key, base[key]),
                                         _by_name(path, key, raw[key]))
    if "train" in raw:
        merged["train"] = {**_mapping(base_path, "train", base.get("train") or {}),
                           **_mapping(path, "train", raw["train"] or {})}
    return merged


def load_recipe(path: str | Path, *, tag_files: dict[str, str | Path] | None = None
                ) -> Recipe:
    """Read and check a recipe's structure (the settings are checked by :func:`check_recipe`);
    ``extends: BASE.yaml`` starts from another recipe (:func:`_raw_recipe`). ``tag_files``:
    a weights file for each tag named that the phases start from (``init: TAG``), used instead
    of the shipped file: a tag that no longer ships, remade by its recipe, or a copy
    (:func:`tag_file_notes` says whether each is the released file)."""
    path = Path(path)
    raw = _raw_recipe(path)
    for key in ("name", "phases"):
        if key not in raw:
            raise _fail(path, "recipe", f"missing key {key!r}")
    steps = []
    for k, item in enumerate(raw.get("data") or []):
        item = _mapping(path, f"data step {k + 1}", item)
        kinds = [key for key in ("scenes", "synth") if key in item]
        extra = sorted(set(item) - {"name", "scenes", "synth"})
        if "name" not in item or len(kinds) != 1 or extra:
            raise _fail(path, f"data step {k + 1}", "expected {name, scenes: {...}} or {name, "
                        "synth: {...}}" + (f"; unknown key(s) {', '.join(extra)}" if extra
                                          else ""))
        steps.append(DataStep(_plain(path, f"data step {k + 1}", item["name"]), kinds[0],
                              dict(_mapping(path, f"data step {item['name']}", item[kinds[0]]))))
    names = [s.name for s in steps]
    if len(set(names)) != len(names):
        raise _fail(path, "data", "step names must be unique")
    phases = []
    raw_phases = raw["phases"]
    if not isinstance(raw_phases, list) or not raw_phases:
        raise _fail(path, "phases", "expected a non-empty list")
    for k, item in enumerate(raw_phases):
        item = _mapping(path, f"phase {k + 1}", item)
        extra = sorted(set(item) - {"name", "set", "init"})
        if "name" not in item or extra:
            raise _fail(path, f"phase {k + 1}", "expected {name, set: {...}, init: ...}"
                        + (f"; unknown key(s) {', '.join(extra)}" if extra else ""))
        init = str(item.get("init", "none" if k == 0 else "previous"))
        if k == 0 and init == "previous":
            raise _fail(path, f"phase {item['name']}", "init: previous, but it is the first phase")
        where = f"phase {item['name']}"
        settings = dict(_mapping(path, where, item.get("set") or {}))
        phases.append(Phase(_plain(path, f"phase {k + 1}", item["name"]),
                            _no_machine_settings(path, where, settings), init))
    if len({p.name for p in phases}) != len(phases):
        raise _fail(path, "phases", "phase names must be unique")
    ship = _ship(path, raw.get("ship"))
    evaluate = []
    for k, item in enumerate(raw.get("evaluate") or []):
        item = dict(_mapping(path, f"evaluate entry {k + 1}", item))
        unknown = sorted(set(item) - {"name", "dataset", "split", *_ENCODING_KEYS})
        if unknown or "name" not in item or "dataset" not in item:
            raise _fail(path, f"evaluate entry {k + 1}", "expected {name, dataset, split} "
                        "and, for raw views, encoding, black_level, white_level")
        _plain(path, f"evaluate entry {k + 1}", item["name"])
        if "split" in item:
            _plain(path, f"evaluate entry {k + 1} split", item["split"])
        try:
            _view_encoding(item)
        except ParameterError as error:
            raise _fail(path, f"evaluate {item['name']}", str(error)) from None
        evaluate.append(item)
    train = dict(_mapping(path, "train", raw.get("train") or {}))
    train = _no_machine_settings(path, "train", train)
    recipe = Recipe(path, _plain(path, "recipe", raw["name"]), str(raw.get("description", "")),
                    steps, train, phases, ship, evaluate)
    recipe.tag_files = _checked_tag_files(recipe, tag_files or {})
    check_recipe(recipe, retired_starts=True)
    return recipe


def _checked_tag_files(recipe: Recipe, tag_files: dict[str, str | Path]) -> dict[str, str]:
    """``tag_files`` with each tag one the phases start from and each path a file."""
    checked, starts = {}, recipe.start_tags
    for tag, path in tag_files.items():
        if tag not in starts:
            raise ParameterError(f"recipe {recipe.path} starts from no tag {tag!r} (the tags its "
                                 f"phases start from: {', '.join(starts) or 'none'})")
        if not Path(path).is_file():
            raise InputFileError(Path(path), f"weights for {tag} not found")
        checked[tag] = str(path)
    return checked


def tag_file_notes(recipe: Recipe) -> list[str]:
    """One line per file given for a tag: whether it is the file the registry released under
    that tag (the same sha256), or other weights (the run then differs from the one that made
    the shipped model)."""
    from dualpixel.weights import DEPRECATED, WEIGHTS, file_sha256

    notes = []
    for tag, path in recipe.tag_files.items():
        released = WEIGHTS[tag].sha256 if tag in WEIGHTS else DEPRECATED.get(tag, {}).get("sha256")
        digest = file_sha256(path)
        if released is None:
            notes.append(f"{tag}: {path} (no released sha256 to compare it with)")
        elif digest == released:
            notes.append(f"{tag}: {path}, the released file (sha256 {digest[:16]}...)")
        else:
            notes.append(f"{tag}: {path} is not the released file (sha256 {digest[:16]}... "
                         f"against {released[:16]}...): the phases from it start from other "
                         "weights than the shipped model's did")
    return notes


# -- resolving -------------------------------------------------------------------------------

def _data_folder(recipe: Recipe, output: Path, value: Any) -> Any:
    """A data step's name -> its folder; other values unchanged (lists element-wise)."""
    if isinstance(value, list):
        return [_data_folder(recipe, output, v) for v in value]
    steps = {s.name for s in recipe.data}
    return str(output / "data" / value) if isinstance(value, str) and value in steps else value


def scene_config(step: DataStep, *, read_photos: bool = True):
    """``(SceneConfig, sequences, seed, photos)`` of a scenes step; ``photos`` (a folder of
    photographs for the photographic layout, relative to the working directory, with
    ``skip_bad``) becomes its :class:`~dualpixel.synthesis.photo_library.PhotoLibrary`, every
    photograph read and checked (``read_photos=False``: None, the folder only looked for)."""
    from dualpixel.synthesis.scenes import SceneConfig, check_sequence_count, photo_library

    args = dict(step.args)
    sequences = check_sequence_count(args.pop("sequences", 1))
    seed = check_seed("seed", args.pop("seed", 0))
    folder, skip_bad = args.pop("photos", None), args.pop("skip_bad", False)
    if not isinstance(skip_bad, bool):
        raise ParameterError(f"skip_bad must be true or false, got {skip_bad!r}")
    if folder is not None and not isinstance(folder, str):
        raise ParameterError(f"photos must be a folder, got {folder!r}")
    config = SceneConfig(**args)
    if not read_photos:
        if folder is not None and config.layout != "photographic":
            raise ParameterError(f"photos are for the photographic layout, not "
                                 f"{config.layout!r}")
        if folder is not None and not Path(folder).is_dir():
            raise InputFileError(folder, "photo folder not found (photos are relative to the "
                                         "working directory)")
        return config, sequences, seed, None
    return config, sequences, seed, photo_library(config, folder, skip_bad=skip_bad)


def synth_config(recipe: Recipe, step: DataStep, output: Path):
    """``(SynthConfig, input folder, format)`` of a synth step."""
    from dualpixel.optics.camera import load_camera
    from dualpixel.synthesis.dataset import SynthConfig

    args = dict(step.args)
    if "input" not in args:
        raise ParameterError("needs input (a data step's name or a folder)")
    source = _data_folder(recipe, output, args.pop("input"))
    fmt = args.pop("format", "rgbd")
    if args.pop("source", "written") not in SYNTH_SOURCES:
        raise ParameterError(f"source must be one of {', '.join(SYNTH_SOURCES)}, got "
                             f"{step.args['source']!r}")
    args = renamed_keys(args, f"{recipe.path}: data step {step.name}")
    if "camera" in args:
        camera = str(args["camera"])  # a shipped camera's name, or a file beside the recipe
        shipped = "/" not in camera and not camera.endswith(".json")
        args["camera"] = load_camera(camera if shipped
                                     else recipe.path.parent / camera).to_dict()
    return SynthConfig(**args), Path(source), fmt


def phase_config(recipe: Recipe, index: int, output: Path, init_weights: str | None):
    """The :class:`TrainConfig` of phase ``index`` (shared settings, then the phase's)."""
    from dualpixel.training.config import load_config

    values = _architecture_keys(recipe.train)
    values.update(_architecture_keys(recipe.phases[index].settings))
    if "init_weights" in values:
        raise ParameterError("init_weights is set by the phase's init (previous, none or a tag)")
    for key in _DATA_KEYS:
        if key in values:
            values[key] = _data_folder(recipe, output, values[key])
    values["init_weights"] = init_weights
    return load_config(None, values)


def _architecture_keys(settings: dict[str, Any]) -> dict[str, Any]:
    """``settings`` with ``architecture: NAME`` replaced by that architecture's keys; a key
    given beside it with another value is refused."""
    from dualpixel.models.spec import ARCHITECTURES

    settings = dict(settings)
    if "architecture" not in settings:
        return settings
    name = str(settings.pop("architecture"))
    if name not in ARCHITECTURES:
        raise ParameterError(f"architecture must be one of {', '.join(ARCHITECTURES)}, got "
                             f"{name!r}")
    keys = {k: list(v) if isinstance(v, tuple) else v for k, v in ARCHITECTURES[name].items()}
    keys.setdefault("refiner", None)  # an architecture without one has none
    clash = [k for k, v in keys.items() if k in settings and settings[k] != v]
    if clash:
        raise ParameterError(f"architecture {name} sets {', '.join(clash)}; give one or the "
                             "other")
    return {**settings, **keys}


def check_recipe(recipe: Recipe, output: Path = Path("OUTPUT"), *,
                 retired_starts: bool = False) -> None:
    """Build every step's and phase's settings (no work done): each error names the recipe, the
    step or phase and the problem. ``retired_starts``: a phase may start from a tag that no
    longer ships and has no file given (reading a recipe; running it needs the file)."""
    steps_seen: set[str] = set()
    for step in recipe.data:
        where = f"data step {step.name}"
        try:
            if step.kind == "scenes":
                scene_config(step, read_photos=False)
            else:
                source = step.args.get("input")
                if isinstance(source, str) and source not in steps_seen and "/" not in source:
                    raise ParameterError(f"input {source!r} is no earlier data step")
                synth_config(recipe, step, output)
        except (ParameterError, TypeError, InputFileError) as error:
            raise _fail(recipe.path, where, str(error)) from None
        steps_seen.add(step.name)
    for index, phase in enumerate(recipe.phases):
        where = f"phase {phase.name}"
        try:
            init = _planned_start(recipe, index, output, retired_starts)
        except (ParameterError, InputFileError) as error:
            raise _fail(recipe.path, where, f"init {phase.init!r} cannot be resolved: "
                                            f"{error}") from None
        try:
            config = phase_config(recipe, index, output, init)
        except (ParameterError, TypeError) as error:
            raise _fail(recipe.path, where, str(error)) from None
        for key in _DATA_KEYS:
            for value in _as_list(getattr(config, key)):
                inside = str(output / "data") + "/"
                if value.startswith(inside) and value[len(inside):] not in steps_seen:
                    raise _fail(recipe.path, where, f"{key} names no data step: {value}")
                if not value.startswith(inside) and not Path(value).is_dir():
                    raise _fail(recipe.path, where, f"{key} {value!r} is no data step of the "
                                                    "recipe and no folder")
    if recipe.ship:
        if "phase" in recipe.ship:
            try:
                recipe.phase_index(str(recipe.ship["phase"]))
            except ParameterError as error:
                raise _fail(recipe.path, "ship", str(error)) from None
    for entry in recipe.evaluate:
        dataset = entry["dataset"]
        if dataset not in steps_seen and "/" not in str(dataset):
            raise _fail(recipe.path, f"evaluate {entry['name']}",
                        f"dataset {dataset!r} is no data step (nor a folder path)")


def phase_start(recipe: Recipe, index: int, output: Path, *, must_exist: bool = True
                ) -> str | None:
    """Where phase ``index`` starts: None (``init: none``), a shipped tag (``init: TAG``,
    checked by its sha256) or, for ``init: previous``, the previous phase's final weights in
    ``output``; when that run is not there (``--from``), the shipped tag that phase made.
    ``must_exist=False`` (a dry run) accepts a previous phase that this run will make."""
    phase = recipe.phases[index]
    if phase.init == "none":
        return None
    if phase.init != "previous":
        return _tag_start(recipe, phase.init)
    previous = recipe.phases[index - 1].name
    weights = recipe.phase_folder(output, index - 1) / "last.safetensors"
    if weights.is_file() or not must_exist:
        return str(weights)
    tags = made_tags(recipe, previous)
    if not tags:
        raise ParameterError(f"phase {phase.name} starts from phase {previous}, which is "
                             f"neither in {output} nor shipped; run that phase first")
    given = [tag for tag in tags if tag in recipe.tag_files]
    return _tag_start(recipe, (given or tags)[0])


def _planned_start(recipe: Recipe, index: int, output: Path, retired_starts: bool) -> str | None:
    """:func:`phase_start` for a plan (a previous phase this run will make is accepted); with
    ``retired_starts``, a tag that no longer ships and has no file given stands for itself."""
    from dualpixel.weights import DEPRECATED

    try:
        return phase_start(recipe, index, output, must_exist=False)
    except (ParameterError, InputFileError):
        if retired_starts and recipe.phases[index].init in DEPRECATED:
            return recipe.phases[index].init  # remade by its own recipe; a run needs its file
        raise


def made_tags(recipe: Recipe, phase: str) -> list[str]:
    """The tags of the weights a phase of ``recipe`` made: the shipped one first, then those
    that no longer ship (:data:`dualpixel.weights.DEPRECATED`)."""
    from dualpixel.weights import DEPRECATED, phase_weights

    shipped = phase_weights(recipe.path.name, phase)
    retired = [tag for tag, entry in DEPRECATED.items()
               if entry.get("recipe") == recipe.path.name and entry.get("phase") == phase]
    return ([shipped] if shipped else []) + retired


def _tag_start(recipe: Recipe, tag: str) -> str:
    """A start tag's weights: the file given for it, else the shipped tag (checked by its
    sha256); a tag that no longer ships says how to make it and how to give its file."""
    from dualpixel.weights import DEPRECATED, deprecation, resolve_tag

    if tag in recipe.tag_files:
        return recipe.tag_files[tag]
    if tag in DEPRECATED:
        phase = DEPRECATED[tag].get("phase")
        made = f"DIR/phases/{phase}/last.safetensors" if phase else "its weights"
        raise ParameterError(f"{deprecation(tag)}; then give {made} for it: --tag-file "
                             f"{tag}=PATH (tag_files in load_recipe)")
    resolve_tag(tag)
    return tag


def _as_list(value: Any) -> list[str]:
    if value is None:
        return []
    return [value] if isinstance(value, str) else list(value)


def plan_text(recipe: Recipe, output: Path, until: str | None = None) -> str:
    """The plan ``--dry-run`` prints: every step and phase with what it changes and its state."""
    lines = [f"recipe {recipe.name} ({recipe.path}) -> {output}", recipe.description, "", "data:"]
    last = recipe.phase_index(until) if until else len(recipe.phases) - 1
    used = {step.name for step in needed_steps(recipe, output, 0, last)}
    for step in recipe.data:
        state = (_step_state(output / "data" / step.name) if step.name in used
                 else "not read: not made")
        args = ", ".join(f"{k}={v}" for k, v in step.args.items())
        lines.append(f"  {step.name:<20} {step.kind}: {args}  [{state}]")
    lines.append("phases:")
    for index, phase in enumerate(recipe.phases[: last + 1]):
        folder = recipe.phase_folder(output, index)
        config = phase_config(recipe, index, output,
                              _planned_start(recipe, index, output, retired_starts=True))
        changes = ", ".join(f"{k}={v}" for k, v in phase.settings.items()) or "(shared only)"
        lines.append(f"  {index + 1:02d} {phase.name:<14} from {phase.init}; {changes}; "
                     f"{config.epochs} x {config.iterations_per_epoch or 'auto'} iterations  "
                     f"[{_phase_state(folder, config.epochs)}]")
    if until is None and recipe.ship:
        settings = ", ".join(f"{k} {v}" for k, v in recipe.output_settings.items())
        lines.append(f"ship: {recipe.shipped_tag} from phase {recipe.shipped_phase} (float16"
                     + (f"; runs with {settings})" if settings else ")"))
        for entry in recipe.evaluate:
            lines.append(f"evaluate: {entry['name']} on {entry['dataset']}")
    return "\n".join(lines)


def _step_state(folder: Path) -> str:
    from dualpixel.synthesis.on_the_fly import is_on_the_fly

    if is_on_the_fly(folder):
        return "done"
    for name in ("dataset.json", "scenes.json"):
        path = folder / name
        if path.is_file():
            try:
                status = read_mapping(path, "folder description").get("status", "complete")
            except InputFileError:
                return "unreadable"
            return "done" if status == "complete" else "started"
    return "to do"


def _phase_epochs(recipe: Recipe, index: int, output: Path) -> int:
    """How many epochs phase ``index`` trains."""
    return phase_config(recipe, index, output,
                        phase_start(recipe, index, output, must_exist=False)).epochs


def phase_done(recipe: Recipe, index: int, output: Path) -> bool:
    """Whether phase ``index`` of a run in ``output`` has trained all its epochs."""
    return (_phase_state(recipe.phase_folder(output, index), _phase_epochs(recipe, index, output))
            == "done")


def phase_finished(recipe: Recipe, index: int, output: Path) -> bool:
    """Whether phase ``index`` of a run in ``output`` trained all its epochs and left its
    weights (``last.safetensors``), with or without the state a resume needs: a run trained on
    another machine comes back without its optimizer state (``last_state.pt``, several times the
    weights' size) and is still finished."""
    folder = recipe.phase_folder(output, index)
    return ((folder / "last.safetensors").is_file()
            and _epochs_recorded(folder) >= _phase_epochs(recipe, index, output))


def _epochs_recorded(folder: Path) -> int:
    """Epochs a phase folder's history records (0 without one)."""
    history = folder / "history.jsonl"
    return (len(read_text_file(history, "training history").splitlines())
            if history.is_file() else 0)


def _phase_state(folder: Path, epochs: int) -> str:
    from dualpixel.training.trainer import has_checkpoint

    if not (folder / "last_state.pt").is_file() or not (folder / "history.jsonl").is_file():
        return "under way, within its first epoch" if has_checkpoint(folder) else "to do"
    done = _epochs_recorded(folder)
    return "done" if done >= epochs else f"{done}/{epochs} epochs"


# -- running -----------------------------------------------------------------------------------

def _claim_folder(recipe: Recipe, output: Path) -> None:
    """Refuse a folder made by another recipe; mark a new one as this recipe's."""
    from dualpixel.io.atomic import atomic_path

    marker = output / "recipe.json"
    if marker.is_file():
        owner = read_mapping(marker, "run folder's recipe record (remove it if the folder is "
                                     "this recipe's)").get("name")
        if owner != recipe.name:
            raise InputFileError(output, f"was made by recipe {owner!r}, not {recipe.name!r} "
                                         f"({recipe.path}); choose another --output")
        return
    output.mkdir(parents=True, exist_ok=True)
    with atomic_path(marker) as tmp:
        tmp.write_text(json.dumps({"name": recipe.name, "recipe": str(recipe.path)}) + "\n")


def _elapsed(started: float) -> str:
    """Time since ``started`` (``time.monotonic()``) as h:mm:ss."""
    seconds = int(time.monotonic() - started)
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


def run_data(recipe: Recipe, output: Path, *, workers: int = 1, progress: bool = True,
             log=print) -> None:
    """Every data step (each resumes; a finished one is checked and skipped)."""
    from dualpixel.synthesis.dataset import synthesize_dataset
    from dualpixel.synthesis.on_the_fly import write_on_the_fly
    from dualpixel.synthesis.scenes import write_scene_folder

    started = time.monotonic()
    for number, step in enumerate(recipe.data, 1):
        folder = output / "data" / step.name
        log(f"[data {number}/{len(recipe.data)}, {_elapsed(started)}] {step.name}: {step.kind}")
        if step.kind == "scenes":
            config, sequences, seed, photos = scene_config(step)
            write_scene_folder(folder, sequences, config, seed=seed, workers=workers,
                               progress=progress, photos=photos)
            continue
        config, source, fmt = synth_config(recipe, step, output)
        if step.args.get("source") == "on-the-fly":  # the recipe of its frames, no frames
            write_on_the_fly(folder, source, fmt, config)
        else:
            summary = synthesize_dataset(source, fmt, folder, config, workers=workers,
                                         device="cpu", progress=progress)
            if summary["status"] != "complete":
                raise InputFileError(folder, "synthesis did not finish; rerun reproduce")


def run_phase(recipe: Recipe, index: int, output: Path, *, overrides: dict[str, Any] | None = None,
              progress: bool = True, log=print) -> Path:
    """Train phase ``index`` (resuming its folder); returns the folder."""
    from dualpixel.training.trainer import has_checkpoint, train

    phase = recipe.phases[index]
    folder = recipe.phase_folder(output, index)
    config = phase_config(recipe, index, output, phase_start(recipe, index, output))
    if overrides:
        config = dataclasses.replace(config, **overrides)
    state = _phase_state(folder, config.epochs)
    if state == "done":
        log(f"phase {phase.name}: done ({folder})")
        return folder
    log(f"phase {phase.name}: {state} -> {folder}")
    train(config, folder, resume=has_checkpoint(folder), progress=progress)
    return folder


def ship_phase(recipe: Recipe, folder: Path, output: Path, phase: str,
               metrics: dict[str, Any] | None = None) -> Path:
    """Export a phase's final weights in float16 with their provenance (and metrics)."""
    import torch

    from dualpixel.models.checkpoint import load_model, read_metadata, save_model
    from dualpixel.models.registry import count_parameters

    source = folder / "last.safetensors"
    meta = read_metadata(source)["extra"]
    model = load_model(source)
    tag = recipe.shipped_tag
    extra = {
        "name": tag, "doc": str(recipe.ship.get("doc", recipe.description)),
        "recipe": recipe.path.name, "phase": phase, "num_params": count_parameters(model),
        "init": meta.get("init"), "metrics": metrics or {},
        "output": recipe.output_settings, "config": meta.get("config"),
    }
    target = output / "ship" / f"{tag}.safetensors"
    target.parent.mkdir(parents=True, exist_ok=True)
    save_model(target, model, dtype=torch.float16, extra=extra)
    return target


#: Keys of an ``evaluate`` entry that say how its views store light (``eval --encoding``).
_ENCODING_KEYS = ("encoding", "black_level", "white_level")


def _view_encoding(entry: dict[str, Any]):
    """The :class:`~dualpixel.inference.encoding.ViewEncoding` of an ``evaluate`` entry
    (display values unless it names ``encoding: linear`` with its levels, in the files'
    units)."""
    from dualpixel.inference.encoding import ViewEncoding

    return ViewEncoding(entry.get("encoding", "srgb"), entry.get("black_level"),
                        entry.get("white_level"))


def evaluate_shipped(recipe: Recipe, weights: Path, output: Path, *, log=print) -> dict:
    """Score the shipped weights, run with the recipe's output settings, on each ``evaluate``
    entry, in float32 on the CPU (the figures of record are the same on every machine, where
    ``auto`` precision would take bfloat16 on some CPUs); returns ``{name: metrics}``."""
    from dualpixel.evaluation.run import EvaluationRequest, run_evaluation
    from dualpixel.inference.pipeline import build_deblurrer

    results = {}
    for entry in recipe.evaluate:
        dataset = Path(_data_folder(recipe, output, entry["dataset"]))
        if not dataset.is_dir():
            log(f"evaluate {entry['name']}: {dataset} not found, skipped")
            continue
        folder = output / "eval" / entry["name"]
        deblurrer = build_deblurrer(weights, device="cpu", precision="fp32",
                                    **recipe.output_settings)
        run_evaluation(EvaluationRequest(output=folder, dataset=dataset,
                                         split=entry.get("split", "test"), niqe=False,
                                         figures=1, encoding=_view_encoding(entry)),
                       deblurrer, "model")
        summary = json.loads((folder / "summary.json").read_text())
        results[entry["name"]] = _mean_scores(summary)
        log(f"evaluate {entry['name']}: {results[entry['name']]}")
    return results


def _mean_scores(summary: dict) -> dict:
    """PSNR / SSIM of the model and the input from an evaluation's ``summary.json``."""
    return {method: {k: round(float(rows["combined"][k]), 4) for k in ("psnr", "ssim")}
            for method, rows in summary["summary"].items()}


def needed_steps(recipe: Recipe, output: Path, first: int, last: int) -> list[DataStep]:
    """The data steps phases ``first..last`` and the evaluation read, with the steps those are
    made from, in recipe order."""
    folders = {str(output / "data" / s.name): s.name for s in recipe.data}
    wanted: set[str] = {e["dataset"] for e in recipe.evaluate if e["dataset"] in
                        {s.name for s in recipe.data}}
    for index in range(first, last + 1):
        config = phase_config(recipe, index, output,
                              _planned_start(recipe, index, output, retired_starts=True))
        for key in _DATA_KEYS:
            wanted |= {folders[v] for v in _as_list(getattr(config, key)) if v in folders}
    for step in reversed(recipe.data):  # inputs come before the steps that read them
        if step.name in wanted and step.kind == "synth" and step.args.get("input") in {
                s.name for s in recipe.data}:
            wanted.add(step.args["input"])
    return [s for s in recipe.data if s.name in wanted]


def check_codecs(recipe: Recipe, output: Path, first: int = 0, last: int | None = None
                 ) -> None:
    """Refuse, before any work, a run whose data must still be coded by a codec that is not
    installed (:meth:`~dualpixel.synthesis.view_coding.ViewCoding.require`): a written step of
    phases ``first..last`` not finished yet, or an on-the-fly step (it codes as it trains)."""
    last = len(recipe.phases) - 1 if last is None else last
    for step in needed_steps(recipe, output, first, last):
        if step.kind != "synth":
            continue
        coding = synth_config(recipe, step, output)[0].coding()
        if coding is None:
            continue
        written = step.args.get("source") != "on-the-fly"
        if written and _step_state(output / "data" / step.name) == "done":
            continue  # coded when it was written
        try:
            coding.require()
        except ParameterError as error:
            raise _fail(recipe.path, f"data step {step.name}", str(error)) from None


def check_machine(machine: dict[str, Any] | None) -> dict[str, Any]:
    """The machine settings of a run (:data:`MACHINE_SETTINGS` keys), checked as
    :class:`TrainConfig` checks them."""
    from dualpixel.training.config import TrainConfig

    machine = dict(machine or {})
    unknown = sorted(set(machine) - set(MACHINE_SETTINGS))
    if unknown:
        raise ParameterError(f"machine settings are {', '.join(MACHINE_SETTINGS)}; got "
                             f"{', '.join(unknown)}")
    if machine:  # the same checks as a config's (ranges, types)
        TrainConfig(synthetic_data="check", **machine)
    return machine


def reproduce(recipe: Recipe, output: str | Path, *, until: str | None = None,
              start: str | None = None, workers: int = 1, progress: bool = True,
              machine: dict[str, Any] | None = None, log=print) -> Path | None:
    """Run the data, every phase (from ``start``, up to ``until``), export and evaluation;
    resumes. Returns the shipped file (None with ``until``).

    ``workers``: processes for the data steps; ``machine``: how each phase runs
    (:data:`MACHINE_SETTINGS`, e.g. ``{"workers": 12, "frame_store": "runs/store"}``; the
    :class:`TrainConfig` defaults otherwise)."""
    output = Path(output)
    machine = check_machine(machine)
    check_recipe(recipe, output)
    for note in tag_file_notes(recipe):
        log(note)
    first = recipe.phase_index(start) if start else 0
    last = recipe.phase_index(until) if until else len(recipe.phases) - 1
    if first > last:
        raise ParameterError(f"--from {start} comes after --until {until}")
    if first > 0:
        phase_start(recipe, first, output)  # a start that cannot be resolved fails now
    check_codecs(recipe, output, first, last)
    from dualpixel.io.lock import folder_lock

    with folder_lock(output, "reproduce"):
        return _reproduce_locked(recipe, output, first, last, until, workers, progress, machine,
                                 log)


def _reproduce_locked(recipe: Recipe, output: Path, first: int, last: int, until: str | None,
                      workers: int, progress: bool, machine: dict[str, Any], log
                      ) -> Path | None:
    """:func:`reproduce` once it holds the run folder's lock."""
    _claim_folder(recipe, output)
    steps = needed_steps(recipe, output, first, last)
    run_data(dataclasses.replace(recipe, data=steps), output, workers=workers,
             progress=progress, log=log)
    started, folders = time.monotonic(), {}
    for i in range(first, last + 1):
        log(f"[phase {i - first + 1}/{last - first + 1}, {_elapsed(started)} into the phases] "
            f"{recipe.phases[i].name}")
        folders[i] = run_phase(recipe, i, output, overrides=machine, progress=progress, log=log)
    if last >= first:
        log(f"phases done in {_elapsed(started)}")
    if until is not None or not recipe.ship:
        return None
    phase = recipe.shipped_phase
    index = recipe.phase_index(phase)
    folder = folders.get(index, recipe.phase_folder(output, index))
    shipped = ship_phase(recipe, folder, output, phase)
    metrics = evaluate_shipped(recipe, shipped, output, log=log)
    shipped = ship_phase(recipe, folder, output, phase, metrics)
    from dualpixel.weights import file_sha256

    log(f"shipped {shipped} (sha256 {file_sha256(shipped)[:16]}...)")
    return shipped
