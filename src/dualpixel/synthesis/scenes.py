"""Procedural RGB-D sequences: a 3-D "dead leaves" world, the built-in default input.

Textured planar shapes ("leaves") at random depths in front of and behind the focal planes of the
camera presets occlude each other (painter's algorithm, far to near) in front of a slanted ground /
back plane. Textures are crops of the natural photographs that scikit-image ships and procedural
dead-leaves textures, which keep natural image statistics (the reason dead-leaves data is used to
train restoration networks). Over a sequence the camera pans (parallax: near leaves move more) and
each leaf drifts and moves in depth, smoothly. Depth is exact, in metres, per frame.

The "photographic" layout makes real photographs most of the frame (a folder of them,
:class:`~dualpixel.synthesis.photo_library.PhotoLibrary`; the package's small set without
one): a whole photograph is the far plane or wall (photographs side by side when none covers
the frame), regions of it that follow its own edges are brought to depths of their own (so
depth edges, and the occlusions at them, fall on real object boundaries, as in a photograph),
and objects cut from other photographs along their edges, or textured by them, stand between
it and the camera; procedural textures are a minority (a quarter of the objects).
"""

from __future__ import annotations

import functools
import json
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import numpy as np

from dualpixel.errors import ParameterError, check_range, check_seed, is_integer
from dualpixel.names import MAX_SEQUENCES, SCENE_LAYOUTS
from dualpixel.parallel import completed
from dualpixel.synthesis.photo_library import PhotoLibrary, shipped_library
from dualpixel.synthesis.textures import dead_leaves, load_photograph, random_texture

__all__ = ["MAX_SEQUENCES", "SCENE_LAYOUTS", "SceneConfig", "check_sequence_count",
           "photo_library", "photo_regions", "photo_side", "render_scene_sequence",
           "write_scene_folder"]

#: "leaves": textured shapes at log-uniform depths before a slanted plane (the original default).
#: "photo": laid out like a photograph: an in-focus subject near the centre (the camera focuses on
#: it), a ground plane receding to a background, objects between them and, sometimes, a blurred
#: foreground occluder; textures from :mod:`dualpixel.synthesis.textures`.
#: "photographic": the "photo" layout's geometry on real photographs (see the module's text).

_PHOTOS = ("astronaut", "coffee", "cat", "rocket", "brick", "grass", "gravel", "camera")


@dataclass(frozen=True)
class SceneConfig:
    """Size and content of a procedural sequence (depths in metres)."""

    width: int = 320
    height: int = 240
    frames: int = 4
    leaves: int = 28
    near: float = 0.5
    far: float = 60.0
    plane_far: float = 150.0
    plane_near: float = 4.0
    camera_speed: float = 6.0  # px per frame for a surface at 1 m ... scaled by 1/depth
    leaf_speed: float = 2.0  # px per frame
    layout: str = "leaves"  # "leaves" (dead-leaves world), "photo" (subject, ground,
    # background) or "photographic" (that geometry on real photographs)
    # Ours: relief of textured surfaces (every shape; the background in the "photo" layout), the
    # largest relative depth change within one (0: flat, as before): depth follows each
    # texture's fine structure, so the blur varies inside objects and their details occlude one
    # another, as on foliage, fabric or gravel.
    relief: float = 0.0

    def __post_init__(self) -> None:
        check_range("width", self.width, 16, 16384)
        check_range("height", self.height, 16, 16384)
        check_range("frames", self.frames, 1, 100000)
        check_range("leaves", self.leaves, 0, 10000)
        check_range("near", self.near, 0.0, self.far, low_inclusive=False)
        check_range("plane_near", self.plane_near, 0.0, self.plane_far, low_inclusive=False)
        check_range("relief", self.relief, 0.0, 0.5)
        if self.layout not in SCENE_LAYOUTS:
            raise ParameterError(
                f"layout must be one of {', '.join(SCENE_LAYOUTS)}, got {self.layout!r}"
            )


def photo_side(config: SceneConfig) -> int:
    """The shortest side (px) a photograph needs to texture ``config``'s scenes unenlarged:
    half the frame's shorter side (a background wider than every photograph is tiled)."""
    return max(min(config.width, config.height) // 2, 16)


def photo_library(config: SceneConfig, folder: str | Path | None, *, skip_bad: bool = False
                  ) -> PhotoLibrary | None:
    """The photographs of ``config``'s scenes: ``folder``'s (checked, see
    :meth:`PhotoLibrary.from_folder`), the package's own for the photographic layout without a
    folder, None for the other layouts (which take no folder)."""
    if config.layout != "photographic":
        if folder is not None:
            raise ParameterError(f"photos are for the photographic layout, not "
                                 f"{config.layout!r}")
        return None
    if folder is None:
        return shipped_library(photo_side(config))
    return PhotoLibrary.from_folder(folder, min_side=photo_side(config), skip_bad=skip_bad)


@functools.lru_cache(maxsize=1)
def _photographs() -> tuple[np.ndarray, ...]:
    """The "leaves" layout's photographs as float32 RGB (grey ones kept grey; tinted later)."""
    photos = []
    for name in _PHOTOS:
        image = load_photograph(name)
        photos.append(np.ascontiguousarray(np.broadcast_to(image, (*image.shape[:2], 3))))
    return tuple(photos)


def _texture(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """A texture patch: a randomly scaled, tinted crop of a photograph, or dead leaves."""
    if rng.uniform() < 0.35:
        return dead_leaves(rng, height, width, r_min=2.0, related_colours=False)
    photo = _photographs()[int(rng.integers(len(_PHOTOS)))]
    scale = max(height / photo.shape[0], width / photo.shape[1]) * rng.uniform(1.0, 2.0)
    resized = cv2.resize(photo, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    y0 = int(rng.integers(resized.shape[0] - height + 1))
    x0 = int(rng.integers(resized.shape[1] - width + 1))
    crop = resized[y0 : y0 + height, x0 : x0 + width]
    tint = rng.uniform(0.6, 1.2, 3).astype(np.float32)
    return np.clip(crop * tint, 0.0, 1.0)


def _leaf_mask(rng: np.random.Generator, size: int) -> np.ndarray:
    """A random convex-ish shape (ellipse, rectangle or polygon) in a ``size`` square, bool."""
    mask = np.zeros((size, size), np.uint8)
    centre = size / 2.0
    kind = int(rng.integers(3))
    if kind == 0:
        axes = (int(size * rng.uniform(0.25, 0.5)), int(size * rng.uniform(0.2, 0.5)))
        cv2.ellipse(mask, (size // 2, size // 2), axes, float(rng.uniform(0, 180)), 0, 360, 1, -1)
    else:
        corners = 4 if kind == 1 else int(rng.integers(5, 9))
        angles = np.sort(rng.uniform(0, 2 * np.pi, corners)) if kind == 2 else (
            np.arange(4) * np.pi / 2 + rng.uniform(0, np.pi / 2)
        )
        radii = size * rng.uniform(0.3, 0.5, corners)
        points = np.stack((centre + radii * np.cos(angles), centre + radii * np.sin(angles)), 1)
        cv2.fillPoly(mask, [np.round(points).astype(np.int32)], 1)
    return mask.astype(bool)


@dataclass
class _Leaf:
    texture: np.ndarray
    mask: np.ndarray
    x: float
    y: float
    depth: float
    vx: float
    vy: float
    depth_rate: float  # relative change of depth per frame
    tilt: float = 0.0  # relative depth change across the leaf's width (a slanted surface)


def _relief(texture: np.ndarray) -> np.ndarray:
    """A texture's relief in [-1, 1], ``(H, W)`` float32: its luminance above or below the local
    mean (Gaussian, 1/16 of its size), normalised; brighter detail lies nearer."""
    luminance = texture.mean(axis=-1).astype(np.float32)
    sigma = max(texture.shape[0], texture.shape[1]) / 16
    detail = luminance - cv2.GaussianBlur(luminance, (0, 0), sigma)
    return np.tanh(detail / (2 * float(detail.std()) + 1e-6)).astype(np.float32)


def _plane_depth(config: SceneConfig, horizon: float) -> np.ndarray:
    """Depth of a slanted plane: inverse depth is linear in the row (perspective of a plane)."""
    rows = np.arange(config.height, dtype=np.float64)[:, None]
    t = np.clip((rows - horizon) / max(config.height - horizon, 1.0), 0.0, 1.0)
    inverse = (1 - t) / config.plane_far + t / config.plane_near
    return np.broadcast_to(1.0 / inverse, (config.height, config.width)).astype(np.float32)


def _photo_world(
    rng: np.random.Generator, config: SceneConfig, margin: int
) -> tuple[np.ndarray, np.ndarray, list[_Leaf], float]:
    """Background image and depth (with margin), shapes and the focus distance of a photo layout."""
    height, width = config.height + 2 * margin, config.width + 2 * margin
    subject = float(np.exp(rng.uniform(np.log(1.0), np.log(6.0))))
    far = subject * float(np.exp(rng.uniform(np.log(2.5), np.log(40.0))))
    background = random_texture(rng, height, width)
    depth = np.full((height, width), far, np.float32)
    if rng.uniform() < 0.65:  # a ground plane from near the camera to the background
        horizon = int(rng.uniform(0.25, 0.75) * height)
        ground = random_texture(rng, height - horizon, width)
        near = subject * rng.uniform(0.35, 1.0)
        t = np.linspace(0.0, 1.0, height - horizon, dtype=np.float64)[:, None]
        background[horizon:] = ground
        depth[horizon:] = 1.0 / ((1 - t) / far + t / near)

    def leaf(size: int, x: float, y: float, d: float, tilt: float = 0.0) -> _Leaf:
        texture = random_texture(rng, size, size)
        return _moving(rng, config, texture, _shape_mask(rng, size), x, y, d, tilt)

    leaves = _arrange(rng, config, leaf, subject, far, objects=(2, 9))
    focus = subject if rng.uniform() < 0.85 else subject * float(np.exp(rng.normal(0, 0.4)))
    return background, depth, leaves, focus


def _moving(rng: np.random.Generator, config: SceneConfig, texture: np.ndarray,
            mask: np.ndarray, x: float, y: float, depth: float, tilt: float = 0.0) -> _Leaf:
    """A shape centred at ``(x, y)`` px at ``depth`` m, drifting and moving in depth."""
    size = mask.shape[0]
    return _Leaf(
        texture=texture, mask=mask, x=x - size / 2, y=y - size / 2, depth=depth,
        vx=config.leaf_speed * rng.normal(), vy=config.leaf_speed * rng.normal() * 0.5,
        depth_rate=rng.normal(0, 0.01), tilt=tilt,
    )


def _arrange(rng: np.random.Generator, config: SceneConfig, leaf, subject: float, far: float,
             *, objects: tuple[int, int], subject_placed=lambda: False) -> list[_Leaf]:
    """The photo layouts' shapes, far to near in drawing order: ``objects`` (a count range)
    between the subject and the background, the subject near the centre (one or two shapes,
    unless ``subject_placed()`` put it elsewhere), sometimes a near occluder at the frame's
    edge. ``leaf(size, x, y, depth, tilt)`` makes each shape."""
    short = min(config.height, config.width)
    leaves = []
    for _ in range(int(rng.integers(*objects))):  # objects between subject and background
        size = int(rng.uniform(0.1, 0.5) * short) + 8
        d = subject * float(np.exp(rng.uniform(np.log(1.1), np.log(far / subject))))
        leaves.append(leaf(size, rng.uniform(-0.1, 1.1) * config.width,
                           rng.uniform(-0.1, 1.1) * config.height, d))
    if not subject_placed():
        for _ in range(int(rng.integers(1, 3))):  # the subject, near the centre, maybe slanted
            size = int(rng.uniform(0.35, 0.85) * short) + 8
            leaves.append(leaf(size, rng.uniform(0.2, 0.8) * config.width,
                               rng.uniform(0.25, 0.8) * config.height,
                               subject * (1 + rng.normal(0, 0.02)), tilt=rng.normal(0, 0.1)))
    if rng.uniform() < 0.35:  # a foreground occluder at the frame's edge
        size = int(rng.uniform(0.2, 0.6) * short) + 8
        x = rng.choice([rng.uniform(-0.2, 0.15), rng.uniform(0.85, 1.2)]) * config.width
        leaves.append(leaf(size, x, rng.uniform(0, 1) * config.height,
                           subject * rng.uniform(0.3, 0.8)))
    return leaves


def photo_regions(rgb: np.ndarray, *, regions: int = 200) -> np.ndarray:
    """Regions of a photograph that follow its edges, ``(H, W)`` int32 labels from 0.

    Felzenszwalb and Huttenlocher's graph segmentation (scikit-image) at half resolution,
    regions of at least ``1 / regions`` of the area: what the photograph's own colour edges
    enclose (objects, their parts), the surfaces a depth map of the scene would follow.
    """
    from skimage.segmentation import felzenszwalb

    height, width = rgb.shape[:2]
    small = cv2.resize(rgb, (max(width // 2, 1), max(height // 2, 1)),
                       interpolation=cv2.INTER_AREA)
    labels = felzenszwalb(small, scale=200, sigma=0.0,  # the half-size image is smooth enough
                          min_size=max(small.shape[0] * small.shape[1] // regions, 4))
    return cv2.resize(labels.astype(np.int32), (width, height), interpolation=cv2.INTER_NEAREST)


def _cut_out(rng: np.random.Generator, texture: np.ndarray) -> np.ndarray | None:
    """The region of ``texture`` (a square photo crop) around its centre, with its neighbours
    that lie mostly inside, as a shape mask along the photograph's own edges; None when that
    region is too small or too large to make an object."""
    size = texture.shape[0]
    labels = photo_regions(texture, regions=60)
    border = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    inside = np.setdiff1d(np.unique(labels), border)
    center = labels[size // 2, size // 2]
    chosen = [center] + [int(k) for k in inside if rng.uniform() < 0.5]
    mask = np.isin(labels, chosen)
    share = float(mask.mean())
    return mask if 0.12 <= share <= 0.85 else None


def _photographic_world(
    rng: np.random.Generator, config: SceneConfig, margin: int, library: PhotoLibrary
) -> tuple[np.ndarray, np.ndarray, list[_Leaf], float]:
    """Background photograph and depth (with margin), shapes and the focus distance of the
    photographic layout: the "photo" layout's subject, background and occluders, on real
    photographs, with the background's own regions at depths of their own."""
    height, width = config.height + 2 * margin, config.width + 2 * margin
    subject = float(np.exp(rng.uniform(np.log(1.0), np.log(6.0))))
    far = subject * float(np.exp(rng.uniform(np.log(1.5), np.log(40.0))))
    background, tiles = library.texture(rng, height, width)
    # the far plane, slanted (inverse depth linear across the frame), maybe with a ground
    # plane receding from near the camera to it; walls side by side each at its own distance
    rows = np.arange(height, dtype=np.float64)[:, None]
    cols = np.arange(width, dtype=np.float64)[None, :]
    angle = rng.uniform(0, 2 * np.pi)
    ramp = (np.cos(angle) * cols / width + np.sin(angle) * rows / height)
    inverse = (1 + rng.uniform(0, 0.6) * (ramp - ramp.min())) / far
    if tiles.max() > 0:
        walls = np.exp(rng.uniform(np.log(subject / far * 1.2), 0.0, int(tiles.max()) + 1))
        inverse = inverse / np.minimum(walls[tiles], 1.0)
    if rng.uniform() < 0.5:
        horizon = int(rng.uniform(0.3, 0.8) * height)
        near = subject * rng.uniform(0.35, 1.0)
        t = np.clip((rows - horizon) / max(height - horizon, 1), 0.0, 1.0)
        inverse = np.maximum(inverse, (1 - t) / far + t / near)
    depth = (1.0 / inverse).astype(np.float32)
    # regions of the photograph brought to their own depths, along its own edges
    labels = photo_regions(background)
    areas = np.bincount(labels.ravel()) / labels.size
    movable = np.flatnonzero((areas >= 0.004) & (areas <= 0.35))
    count = int(rng.integers(0, min(len(movable), 12) + 1))
    for k in rng.permutation(movable)[:count]:  # most behind the subject, as in photographs
        low, high = (0.6, 0.95) if rng.uniform() < 0.2 else (1.05, far / subject)
        depth[labels == k] = subject * float(np.exp(rng.uniform(np.log(low), np.log(high))))

    def texture(size: int) -> np.ndarray:
        if rng.uniform() < 0.25 or not len(library.covering(size, size)):
            return random_texture(rng, size, size)  # procedural: a minority
        return library.crop(rng, size, size)

    def leaf(size: int, x: float, y: float, d: float, tilt: float = 0.0) -> _Leaf:
        rgb = texture(size)
        mask = _cut_out(rng, rgb) if rng.uniform() < 0.5 else None
        return _moving(rng, config, rgb, _shape_mask(rng, size) if mask is None else mask,
                       x, y, d, tilt)

    def subject_region() -> bool:
        """The subject as a region of the background itself, sometimes."""
        regions = [k for k in movable if 0.01 <= areas[k] <= 0.2]
        if regions and rng.uniform() < 0.35:
            depth[labels == int(rng.choice(regions))] = subject
            return True
        return False

    leaves = _arrange(rng, config, leaf, subject, far, objects=(1, 7),
                      subject_placed=subject_region)
    focus = subject if rng.uniform() < 0.85 else subject * float(np.exp(rng.normal(0, 0.4)))
    return background, depth, leaves, focus


def _shape_mask(rng: np.random.Generator, size: int) -> np.ndarray:
    """A geometric shape (see :func:`_leaf_mask`) or an organic blob (thresholded smooth noise)."""
    if rng.uniform() < 0.6:
        return _leaf_mask(rng, size)
    noise = cv2.GaussianBlur(rng.normal(size=(size, size)).astype(np.float32), (0, 0), size / 8)
    yy, xx = np.mgrid[0:size, 0:size]
    falloff = np.hypot(yy - size / 2, xx - size / 2) / (size / 2)
    field = noise / (noise.std() + 1e-6) - 2.5 * falloff**2
    return field > 0.0


def render_scene_sequence(
    seed: int, config: SceneConfig, photos: PhotoLibrary | None = None
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Render one sequence: a list of ``(rgb float32 (H, W, 3) in [0, 1], depth float32 (H, W))``.

    The same ``seed``, ``config`` and ``photos`` (the photographic layout's photographs; the
    package's own without them) always give the same frames.
    """
    return render_scene(seed, config, photos)[0]


def render_scene(
    seed: int, config: SceneConfig, photos: PhotoLibrary | None = None
) -> tuple[list[tuple[np.ndarray, np.ndarray]], float | None]:
    """Like :func:`render_scene_sequence`, with the focus distance (m) of the "photo" and
    "photographic" layouts (the subject's depth, or occasionally a missed focus), None for
    "leaves"."""
    rng = np.random.default_rng(check_seed("seed", seed))
    height, width = config.height, config.width
    pan = config.camera_speed * rng.uniform(-1, 1, 2) * np.array([1.0, 0.3])
    margin = int(abs(pan).max() * config.frames / config.plane_near) + 8
    focus = None
    if config.layout in ("photo", "photographic"):
        if config.layout == "photo":
            background, back_depth, leaves, focus = _photo_world(rng, config, margin)
        else:
            library = photo_library(config, None) if photos is None else photos
            background, back_depth, leaves, focus = _photographic_world(rng, config, margin,
                                                                        library)
        parallax_depth = float(np.median(back_depth))
        if config.relief:
            back_depth = back_depth * (1 - config.relief * _relief(background))
    else:
        background = _texture(rng, height + 2 * margin, width + 2 * margin)
        horizon = rng.uniform(-0.3, 0.5) * height
        back_depth = None
        plane = _plane_depth(config, horizon)
        parallax_depth = float(np.mean(plane))
        leaves = []
        for _ in range(config.leaves):
            size = int(rng.uniform(0.12, 0.55) * min(height, width)) + 8
            leaves.append(_Leaf(
                texture=_texture(rng, size, size),
                mask=_leaf_mask(rng, size),
                x=rng.uniform(-0.2, 1.2) * width - size / 2,
                y=rng.uniform(-0.2, 1.2) * height - size / 2,
                depth=float(np.exp(rng.uniform(np.log(config.near), np.log(config.far)))),
                vx=config.leaf_speed * rng.normal(),
                vy=config.leaf_speed * rng.normal() * 0.5,
                depth_rate=rng.normal(0, 0.02),
            ))
    reliefs = [_relief(leaf.texture) if config.relief else None for leaf in leaves]
    frames = []
    for t in range(config.frames):
        # the background scrolls with the camera at the parallax of its typical depth
        shift = pan * t / parallax_depth
        ox, oy = round(margin + shift[0]), round(margin + shift[1])
        rgb = background[oy : oy + height, ox : ox + width].copy()
        depth = (plane.copy() if back_depth is None
                 else back_depth[oy : oy + height, ox : ox + width].copy())
        placed = []
        for leaf, relief in zip(leaves, reliefs, strict=True):
            d = leaf.depth * (1.0 + leaf.depth_rate) ** t
            x = leaf.x + (leaf.vx + pan[0] / d) * t
            y = leaf.y + (leaf.vy + pan[1] / d) * t
            placed.append((d, round(x), round(y), leaf, relief))
        for d, x, y, leaf, relief in sorted(placed, key=lambda item: -item[0]):  # far to near
            size = leaf.mask.shape[0]
            x0, y0, x1, y1 = max(x, 0), max(y, 0), min(x + size, width), min(y + size, height)
            if x0 >= x1 or y0 >= y1:
                continue
            mask = leaf.mask[y0 - y : y1 - y, x0 - x : x1 - x]
            rgb[y0:y1, x0:x1][mask] = leaf.texture[y0 - y : y1 - y, x0 - x : x1 - x][mask]
            leaf_depth = np.full(mask.shape, d, np.float32)
            if leaf.tilt:
                ramp = (np.arange(x0 - x, x1 - x, dtype=np.float32) / size - 0.5) * leaf.tilt
                leaf_depth = leaf_depth * (1 + ramp)[None, :]
            if relief is not None:
                leaf_depth = leaf_depth * (1 - config.relief * relief[y0 - y : y1 - y,
                                                                      x0 - x : x1 - x])
            depth[y0:y1, x0:x1][mask] = leaf_depth[mask]
        frames.append((np.ascontiguousarray(rgb), np.ascontiguousarray(depth, np.float32)))
    return frames, focus


SCENES_DESCRIPTION = "scenes.json"


def _check_description(root: Path, settings: dict) -> None:
    """Refuse a folder holding scenes made with other settings (kept frames would not match),
    or sequences without a description; make the folder."""
    from dualpixel.errors import InputFileError
    from dualpixel.io.documents import read_mapping
    from dualpixel.io.run_folder import differing_settings

    path = root / SCENES_DESCRIPTION
    if path.is_file():
        existing = read_mapping(path, "scenes description (remove the folder and rerun)")
        # the photographs are compared by content, wherever their folder is given from
        differ = differing_settings(settings, existing,
                                    ignore=("status", "sequences", "folder"))
        if differ:
            raise InputFileError(root, "holds scenes made with other settings (differs in "
                                       f"{', '.join(differ)}); choose another output folder")
        return
    if root.is_dir() and any(root.glob("seq_*")):
        raise InputFileError(root, f"holds sequences without a {SCENES_DESCRIPTION} (made by "
                                   "something else); choose another output folder")
    root.mkdir(parents=True, exist_ok=True)


def _write_description(root: Path, settings: dict, status: str, sequences: int = 0) -> None:
    """The folder's settings with its completion mark: ``status`` "incomplete" until every
    sequence is written (:func:`check_scenes_complete`)."""
    from dualpixel.io.atomic import atomic_path

    record = {**settings, "status": status, **({"sequences": sequences} if sequences else {})}
    with atomic_path(root / SCENES_DESCRIPTION) as tmp:
        tmp.write_text(json.dumps(record, indent=2, sort_keys=True) + "\n")


def check_scenes_complete(root: str | Path) -> None:
    """Refuse a folder of :func:`write_scene_folder` whose writing was interrupted (its
    description says "incomplete"); folders of other tools, without a description, pass."""
    from dualpixel.errors import InputFileError
    from dualpixel.io.documents import read_mapping

    path = Path(root) / SCENES_DESCRIPTION
    if path.is_file():
        status = read_mapping(path, "scenes description").get("status", "complete")
        if status != "complete":
            raise InputFileError(root, "is an unfinished `dualpixel scenes` folder (its "
                                       "writing was interrupted); rerun the same `dualpixel "
                                       "scenes` command to finish it")


def check_sequence_count(sequences: object) -> int:
    """``sequences`` if it is an integer in [1, :data:`MAX_SEQUENCES`], else a
    :class:`ParameterError`."""
    if not is_integer(sequences) or not 1 <= int(sequences) <= MAX_SEQUENCES:
        raise ParameterError(f"sequences must be an integer in [1, {MAX_SEQUENCES}], "
                             f"got {sequences!r}")
    return int(sequences)


def write_scene_folder(
    output: str | Path, sequences: int, config: SceneConfig, *, seed: int = 0,
    progress: bool = True, workers: int = 1, photos: PhotoLibrary | None = None,
) -> list[Path]:
    """Write procedural sequences as an RGB-D folder: ``seq_NNN/rgb/*.png`` (8-bit),
    ``seq_NNN/depth/*.npy`` (float32 metres) and, for the "photo" and "photographic" layouts,
    ``seq_NNN/scene.json`` with the focus distance (read by defocus profiles). Sequence k uses
    seed ``(seed, k)``, so the folder is the same whatever ``workers`` (parallel processes);
    files are written atomically and existing complete sequences are kept. ``photos``: the
    photographic layout's photographs (:class:`PhotoLibrary`; the package's own without it),
    recorded in ``scenes.json`` by folder, count and digest."""
    from dualpixel.io.atomic import remove_partials
    from dualpixel.io.lock import folder_lock
    from dualpixel.progress import progress_bar

    check_range("workers", workers, low=1)
    check_seed("seed", seed)
    if photos is None:  # the layout's default: the package's photographs, or none
        photos = photo_library(config, None)
    elif config.layout != "photographic":
        raise ParameterError(f"photographs are for the photographic layout, not "
                             f"{config.layout!r}")
    sequences = check_sequence_count(sequences)
    root = Path(output)
    folders = [root / f"seq_{k:03d}" for k in range(sequences)]
    names = [f"frame_{t:04d}" for t in range(config.frames)]
    with folder_lock(root, "scenes"):
        settings = asdict(config)
        if not settings["relief"]:  # as recorded before the setting existed
            del settings["relief"]
        description = {"config": settings, "seed": seed,
                       **({"photos": photos.describe()} if photos is not None else {})}
        _check_description(root, description)
        remove_partials(root)  # temporary files of writes a kill interrupted
        missing = [(folder, k, names, config, seed, photos) for k, folder in enumerate(folders)
                   if not all((folder / "depth" / f"{n}.npy").is_file()
                              and (folder / "rgb" / f"{n}.png").is_file() for n in names)]
        if missing:
            _write_description(root, description, "incomplete")
        with progress_bar(total=sequences, initial=sequences - len(missing),
                          desc="rendering scenes", unit="seq", enabled=progress) as bar:
            for _ in completed(_write_sequence, missing, workers):
                bar.update()
        _write_description(root, description, "complete", sequences)
    return folders


def _write_sequence(folder: Path, k: int, names: list[str], config: SceneConfig,
                    seed: int, photos: PhotoLibrary | None) -> None:
    """Render sequence ``k`` of the folder (seed ``(seed, k)``) and write its frames as
    ``names``."""
    from dualpixel.io.atomic import atomic_path
    from dualpixel.io.images import save_npy, write_png

    sequence_seed = int(np.random.SeedSequence((seed, k)).generate_state(1)[0])
    frames, focus = render_scene(sequence_seed, config, photos)
    if focus is not None:
        with atomic_path(folder / "scene.json") as tmp:
            tmp.write_text(json.dumps({"focus_distance": focus, "layout": config.layout}))
    for name, (rgb, depth) in zip(names, frames):
        write_png(folder / "rgb" / f"{name}.png", rgb, bit_depth=8)
        save_npy(folder / "depth" / f"{name}.npy", depth)
