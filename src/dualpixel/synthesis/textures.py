"""Natural-looking surface textures for procedural scenes, with nothing downloaded.

Sources, drawn at random:

- 15 public-domain and CC0 photographs shipped with the package (``photographs/``, their
  sources and licences in ``photographs/SOURCES.md``), as random crops at random scale,
  rotation, flip and colour (grey images get a random two-colour mapping, colour ones a random
  tint and channel mix);
- dead leaves (occluding disks with power-law radii: the scale-invariant statistics of natural
  images, the reason they train restoration networks);
- coloured fractal noise with a 1/f^p amplitude spectrum (foliage, rock, bark when anisotropic);
- printed text and thin lines (the sharp, high-contrast edges of man-made scenes);
- smooth gradients with a little noise (sky, walls).

Every texture is float32 ``(H, W, 3)`` in [0, 1], reproducible from the generator it is given
and the package's version alone (no installed package's data is read).
"""

from __future__ import annotations

import functools
from importlib import resources
from pathlib import Path

import cv2
import numpy as np

__all__ = ["PHOTOGRAPH_NAMES", "load_photograph", "photograph_path", "photographs",
           "random_texture"]

#: The shipped photographs (``photographs/NAME.png``), in the order textures draw them.
PHOTOGRAPH_NAMES: tuple[str, ...] = (
    "astronaut", "brick", "camera", "cat", "cell", "clock", "coffee", "coins", "grass",
    "gravel", "hubble_deep_field", "immunohistochemistry", "retina", "rocket", "text",
)


def photograph_path(name: str) -> Path:
    """The file of one shipped photograph (``KeyError`` for a name not shipped)."""
    if name not in PHOTOGRAPH_NAMES:
        raise KeyError(f"unknown photograph {name!r}; shipped: {', '.join(PHOTOGRAPH_NAMES)}")
    return Path(str(resources.files("dualpixel.synthesis").joinpath("photographs", f"{name}.png")))


def load_photograph(name: str) -> np.ndarray:
    """One shipped photograph by name, float32 ``(H, W, 1 or 3)`` RGB in [0, 1]."""
    path = photograph_path(name)
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:  # a broken installation, not a user error
        raise FileNotFoundError(f"{path}: shipped photograph missing or unreadable; "
                                "reinstall dualpixel")
    image = image[:, :, None] if image.ndim == 2 else image[:, :, 2::-1]
    return np.ascontiguousarray(image, dtype=np.float32) / 255.0


@functools.lru_cache(maxsize=1)
def photographs() -> tuple[np.ndarray, ...]:
    """All shipped photographs in :data:`PHOTOGRAPH_NAMES` order, float32 ``(H, W, 1 or 3)``."""
    return tuple(load_photograph(name) for name in PHOTOGRAPH_NAMES)


def _colourise(rng: np.random.Generator, image: np.ndarray) -> np.ndarray:
    """Grey -> random two-colour map; colour -> random channel mix and tint."""
    if image.shape[2] == 1:
        low, high = rng.uniform(0.0, 0.5, 3), rng.uniform(0.5, 1.0, 3)
        return (low + image * (high - low)).astype(np.float32)
    mix = np.eye(3) * rng.uniform(0.6, 1.0) + rng.uniform(-0.15, 0.25, (3, 3))
    mix /= mix.sum(axis=1, keepdims=True)
    out = image @ mix.T.astype(np.float32)
    return out * rng.uniform(0.7, 1.2, 3).astype(np.float32)


def _photo_crop(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    photos = photographs()
    photo = photos[int(rng.integers(len(photos)))]
    angle = float(rng.choice([0, 90, 180, 270])) + rng.normal(0, 10)
    # scale: from downsampled (denser detail than the original) to mildly enlarged; areas beyond
    # the photograph are filled by mirroring it
    scale = float(np.exp(rng.uniform(np.log(0.25), np.log(1.2))))
    centre = (photo.shape[1] / 2.0, photo.shape[0] / 2.0)
    matrix = cv2.getRotationMatrix2D(centre, angle, scale)
    matrix[:, 2] += (width / 2.0 - centre[0], height / 2.0 - centre[1])
    matrix[:, 2] += rng.uniform(-0.25, 0.25, 2) * photo.shape[1::-1] * scale
    interp = cv2.INTER_AREA if scale < 1 else cv2.INTER_CUBIC
    warped = cv2.warpAffine(photo, matrix, (width, height), flags=interp,
                            borderMode=cv2.BORDER_REFLECT_101)
    if warped.ndim == 2:
        warped = warped[:, :, None]
    if rng.uniform() < 0.5:
        warped = warped[:, ::-1]
    return _colourise(rng, np.ascontiguousarray(warped))


def dead_leaves(rng: np.random.Generator, height: int, width: int, *,
                r_min: float | None = None, related_colours: bool = True) -> np.ndarray:
    """Opaque disks with density ~ r^-3 (scale invariance) on a random background, ``(H, W, 3)``.

    ``r_min``: the smallest radius in pixels (drawn from [1, 3] when ``None``); the largest is a
    third of the longer side. ``related_colours``: disk colours scattered around one base colour
    (as in natural images); otherwise each drawn independently (the "leaves" scene layout).
    """
    canvas = np.empty((height, width, 3), np.float32)
    canvas[:] = rng.uniform(0.05, 0.95, 3)
    if r_min is None:
        r_min = float(rng.uniform(1.0, 3.0))
    r_max = max(height, width) / 3.0
    base = rng.uniform(0.1, 0.9, 3) if related_colours else None
    for _ in range(height * width // 40 + 50):
        # radius drawn by inverting the CDF of the r^-3 density on [r_min, r_max]
        u = rng.uniform()
        radius = (r_min**-2 - u * (r_min**-2 - r_max**-2)) ** -0.5
        centre = (int(rng.integers(width)), int(rng.integers(height)))
        if base is not None:
            colour = np.clip(base + rng.normal(0, 0.3, 3), 0.02, 0.98)
        else:
            colour = rng.uniform(0.02, 0.98, 3)
        cv2.circle(canvas, centre, round(radius), tuple(float(c) for c in colour), -1,
                   lineType=cv2.LINE_AA)
    return canvas


def fractal_noise(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """Coloured noise with amplitude ~ 1/f^p (p in [0.8, 1.6]), optionally anisotropic."""
    fy = np.fft.fftfreq(height)[:, None]
    fx = np.fft.rfftfreq(width)[None, :]
    stretch = float(np.exp(rng.uniform(0, np.log(6)))) if rng.uniform() < 0.4 else 1.0
    angle = rng.uniform(0, np.pi)
    u = fx * np.cos(angle) + fy * np.sin(angle)
    v = -fx * np.sin(angle) + fy * np.cos(angle)
    radius = np.sqrt((u * stretch) ** 2 + v**2)
    radius[0, 0] = 1.0
    amplitude = radius ** -rng.uniform(0.8, 1.6)
    amplitude[0, 0] = 0.0
    channels = []
    for _ in range(2):
        phase = rng.normal(size=(height, fx.shape[1])) + 1j * rng.normal(size=(height, fx.shape[1]))
        field = np.fft.irfft2(phase * amplitude, s=(height, width))
        channels.append((field - field.mean()) / (field.std() + 1e-12))
    c0, c1 = rng.uniform(0, 1, 3), rng.uniform(0, 1, 3)
    contrast = rng.uniform(0.1, 0.35)
    mean = (c0 + c1) / 2
    out = mean + contrast * (channels[0][..., None] * (c1 - c0) * 2 + 0.5 * channels[1][..., None])
    return np.clip(out, 0, 1).astype(np.float32)


def text_and_lines(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """Printed text, thin lines and rectangles on a plain or gradient background."""
    background = rng.uniform(0.1, 0.95, 3)
    canvas = np.empty((height, width, 3), np.uint8)  # OpenCV draws text on 8-bit images only
    canvas[:] = np.round(background * 255)
    fonts = (cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_DUPLEX, cv2.FONT_HERSHEY_COMPLEX,
             cv2.FONT_HERSHEY_TRIPLEX, cv2.FONT_HERSHEY_PLAIN)
    letters = np.array(list("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789 "))
    for _ in range(int(rng.integers(3, 20))):
        colour = tuple(int(c) for c in np.clip(1 - background + rng.normal(0, 0.2, 3), 0, 1) * 255)
        kind = rng.uniform()
        if kind < 0.6:
            text = "".join(rng.choice(letters, int(rng.integers(3, 16))))
            origin = (int(rng.integers(-20, width)), int(rng.integers(0, height + 20)))
            scale = float(np.exp(rng.uniform(np.log(0.3), np.log(2.5))))
            cv2.putText(canvas, text, origin, fonts[int(rng.integers(len(fonts)))], scale, colour,
                        int(rng.integers(1, 4)), cv2.LINE_AA)
        elif kind < 0.85:
            p0 = (int(rng.integers(width)), int(rng.integers(height)))
            p1 = (int(rng.integers(width)), int(rng.integers(height)))
            cv2.line(canvas, p0, p1, colour, int(rng.integers(1, 4)), cv2.LINE_AA)
        else:
            p0 = (int(rng.integers(width)), int(rng.integers(height)))
            size = (int(rng.integers(4, max(width // 3, 5))),
                    int(rng.integers(4, max(height // 3, 5))))
            cv2.rectangle(canvas, p0, (p0[0] + size[0], p0[1] + size[1]), colour,
                          int(rng.choice([-1, 1, 2])), cv2.LINE_AA)
    return canvas.astype(np.float32) / 255.0


def smooth_gradient(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """A smooth colour gradient with faint fine noise (sky, walls)."""
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    angle = rng.uniform(0, 2 * np.pi)
    t = (xs * np.cos(angle) + ys * np.sin(angle)) / max(height, width)
    t = (t - t.min()) / max(float(np.ptp(t)), 1e-6)
    c0, c1 = rng.uniform(0.1, 0.95, 3), rng.uniform(0.1, 0.95, 3)
    out = c0 + t[..., None] * (c1 - c0)
    out += rng.normal(0, rng.uniform(0.0, 0.02), out.shape)
    return np.clip(out, 0, 1).astype(np.float32)


_GENERATORS = (
    (0.50, _photo_crop), (0.17, dead_leaves), (0.18, fractal_noise), (0.10, text_and_lines),
    (0.05, smooth_gradient),
)


def random_texture(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """A ``(height, width, 3)`` float32 texture in [0, 1] from one of the module's sources."""
    weights = np.array([w for w, _ in _GENERATORS])
    generator = _GENERATORS[int(rng.choice(len(_GENERATORS), p=weights / weights.sum()))][1]
    return np.clip(generator(rng, height, width), 0.0, 1.0).astype(np.float32)
