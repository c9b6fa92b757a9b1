"""Reading measured PSF stacks (``.npy`` arrays or the ``.npz`` of ``calibrate estimate-psf``)."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from dualpixel.errors import InputFileError
from dualpixel.io.images import load_npy, numpy_load_problem

__all__ = ["load_measured_psfs"]


def load_measured_psfs(path: str | Path, view: str) -> np.ndarray:
    """The PSFs of ``view`` ("left", "right", "combined") in ``path`` as float64 ``(N, S, S)``
    with odd ``S``: a ``.npy`` holds one view's stack, an ``.npz`` one array per view.

    Every PSF must be finite, non-negative and have a positive sum.
    """
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "file not found")
    suffix = path.suffix.lower()
    if suffix not in (".npy", ".npz"):
        raise InputFileError(path, f"expected a .npy or .npz PSF file, got {suffix or 'no suffix'}")
    try:
        if suffix == ".npy":
            data = load_npy(path)
        else:
            with np.load(path, allow_pickle=False) as archive:
                if view not in archive:
                    raise InputFileError(path, f"has no '{view}' array (it holds "
                                               f"{', '.join(archive.files) or 'none'})")
                data = archive[view]
    except InputFileError:
        raise  # load_npy's or a missing view's, naming the file already
    except (OSError, ValueError, zipfile.BadZipFile) as error:
        raise InputFileError(path, numpy_load_problem(error)) from None
    data = np.asarray(data, np.float64)
    if data.ndim == 2:
        data = data[None]
    if data.ndim != 3 or data.shape[1] != data.shape[2] or data.shape[1] % 2 == 0:
        raise InputFileError(path, f"expected PSFs of shape (N, S, S) with odd S, got {data.shape}")
    if len(data) == 0:
        raise InputFileError(path, "holds no PSFs")
    if not np.isfinite(data).all() or (data < -1e-6).any():
        raise InputFileError(path, "PSFs must be finite and non-negative")
    empty = np.flatnonzero(data.sum(axis=(1, 2)) <= 0)
    if len(empty):
        raise InputFileError(path, f"PSF(s) {', '.join(map(str, empty[:5]))} sum to zero")
    return data
