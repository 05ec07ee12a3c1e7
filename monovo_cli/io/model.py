"""The ground model file (``model.npz``): a keyframe's observation points and plane.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.atomic import atomic_write_bytes


def save_model(path: Path, keyframe, camera, region) -> None:
    """Save a ground model (a :class:`~monovo_cli.core.keyframe.Keyframe`) of ``camera`` and
    ``region`` (x0, y0, x1, y1 px) to ``model.npz`` atomically."""
    path = Path(path)
    arrays = {
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
    from monovo_cli.core.estimate import KeyLevel
    from monovo_cli.core.ground import LevelPoints
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
