"""The ground model file (``model.npz``): a keyframe's observation points and plane.

Besides the points, the file records what they were built from (:func:`read_model_record`):
the SHA-256 of frame 0's decoded grey image (:func:`image_sha256`), the tracking options
given to ``monovo init`` and the mask's fingerprint, so that ``monovo track --model`` can
refuse a model of another sequence or built with other options. The camera, plane and
region are in the file anyway.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.atomic import atomic_write_bytes


def image_sha256(image: np.ndarray) -> str:
    """SHA-256 (hex) of a decoded image (H, W) as float32 grey levels, its shape included:
    the same for any file format holding the same pixels."""
    a = np.ascontiguousarray(image, dtype=np.float32)
    h = hashlib.sha256(f"{a.shape}".encode())
    h.update(a.tobytes())
    return h.hexdigest()


def save_model(path: Path, keyframe, camera, region, *, frame0: np.ndarray | None = None,
               options: Any = None, mask: np.ndarray | None = None) -> None:
    """Save a ground model (a :class:`~monovo_cli.core.keyframe.Keyframe`) of ``camera`` and
    ``region`` (x0, y0, x1, y1 px) to ``model.npz`` atomically, with the fingerprint of the
    ``frame0`` image (H, W) it was built from, the TrackOptions ``options`` and the fingerprint
    of the ``mask`` (H, W) bool of usable pixels it was built with."""
    path = Path(path)
    record = {"frame0_sha256": image_sha256(frame0) if frame0 is not None else None,
              "options": dataclasses.asdict(options) if options is not None else None,
              "mask_sha256": image_sha256(mask) if mask is not None else None}
    arrays = {
        "record": np.array(json.dumps(record, sort_keys=True)),
        "format": np.array("monovo-model-1"),
        "camera": np.array([camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy]),
        "distortion": np.asarray(camera.distortion, dtype=float),
        "region": np.asarray(region, dtype=int),
        "normal": keyframe.plane.normal,
        "distance": np.array(keyframe.plane.distance),
        "corners": keyframe.corners,
        "noise_sigma": np.array(keyframe.noise_sigma),
        "threshold": np.array(keyframe.threshold),
        "levels": np.array(len(keyframe.levels)),
    }
    for lv, kl in enumerate(keyframe.levels):
        p = kl.points
        for name in ("uv", "X", "intensity", "grad", "tri", "bary"):
            arrays[f"l{lv}_{name}"] = getattr(p, name)
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def load_model(path: Path):
    """Load ``model.npz``: returns ``(camera, region, keyframe)``, a
    :class:`~monovo_cli.geometry.camera.PinholeCamera`, the region (x0, y0, x1, y1) px and the
    frame-0 :class:`~monovo_cli.core.keyframe.Keyframe`. InputError when the file is not a
    model or is damaged."""
    from monovo_cli.core.estimator.estimate import KeyLevel
    from monovo_cli.core.estimator.ground import LevelPoints
    from monovo_cli.core.keyframe import Keyframe
    from monovo_cli.geometry.camera import PinholeCamera
    from monovo_cli.geometry.plane import Plane

    path = Path(path)
    not_model = f"{path}: not a monovo model (write one with 'monovo init')"
    damaged = f"{path}: damaged or incomplete model; write it again with 'monovo init'"
    try:
        with open(path, "rb") as f:
            if f.read(4) != b"PK\x03\x04":  # an .npz is a zip archive
                raise InputError(not_model)
        with np.load(path, allow_pickle=False) as z:
            if "format" not in z or str(z["format"]) != "monovo-model-1":
                raise InputError(not_model)
            d = {k: z[k] for k in z.files}
    except InputError:
        raise
    except OSError as exc:
        raise InputError(f"{path}: cannot read model ({exc.strerror or exc})") from None
    except Exception:  # noqa: BLE001 - numpy's npy/zip readers raise ValueError, BadZipFile,
        # zlib.error, EOFError, even SyntaxError/TokenError on a damaged header: all mean the same
        raise InputError(damaged) from None
    try:
        c = d["camera"]
        camera = PinholeCamera(int(c[0]), int(c[1]), float(c[2]), float(c[3]), float(c[4]),
                               float(c[5]), tuple(float(v) for v in d["distortion"]))
        plane = Plane(d["normal"].astype(float), float(d["distance"]))
        levels = []
        for lv in range(int(d["levels"])):
            pts = LevelPoints(lv, camera.scaled(lv), *(d[f"l{lv}_{n}"] for n in
                                                       ("uv", "X", "intensity", "grad")),
                              d["corners"])
            levels.append(KeyLevel.from_points(pts))
        key = Keyframe(0, np.eye(4), plane, d["corners"], tuple(levels), float(d["noise_sigma"]),
                       float(d["threshold"]))
        region = tuple(int(v) for v in d["region"])
    except (KeyError, ValueError, IndexError, TypeError):
        raise InputError(damaged) from None
    return camera, region, key


def read_model_record(path: Path) -> dict[str, Any]:
    """What ``model.npz`` says it was built from: ``frame0_sha256`` (str), ``options`` (the
    TrackOptions given to init, as a dict), ``mask_sha256`` (str); each None when unknown (a
    model written before monovo recorded it). Call after :func:`load_model` succeeded."""
    empty = {"frame0_sha256": None, "options": None, "mask_sha256": None}
    try:
        with np.load(Path(path), allow_pickle=False) as z:
            if "record" not in z:
                return empty
            record = json.loads(str(z["record"]))
    except Exception:  # noqa: BLE001 - same family of failures as in load_model
        raise InputError(f"{path}: damaged or incomplete model; write it again with "
                         "'monovo init'") from None
    if not isinstance(record, dict):
        raise InputError(f"{path}: damaged or incomplete model; write it again with 'monovo init'")
    return {k: record.get(k) for k in empty}
