"""What init.yaml says of the ground besides frame 0's plane (:class:`Mounting`), and the
images' verdict on its tilt (:class:`InitialTilt`): the inputs and the first finding of
:class:`~monovo_cli.core.plane.tracker.PlaneTracker`.
"""

from __future__ import annotations

from dataclasses import dataclass

from monovo_cli.core.plane.belief import CONSISTENT_CHI2, default_sigmas
from monovo_cli.geometry.plane import Plane


@dataclass(frozen=True)
class Mounting:
    """What init.yaml says of the ground besides frame 0's plane.

    ``sigma_distance`` (m) and ``sigma_deg``: how far the ground under the rover departs from
    its mean mount (None: :func:`~monovo_cli.core.plane.belief.default_sigmas`); ``mount``
    the declared nominal mount, a plane in the camera frame (None: the mean mount is latent,
    estimated from the drive); ``initial_std`` ``(m, deg)`` the std of frame 0's plane (None:
    exact; ``ground.nominal: true`` gives the prior's width).
    """

    sigma_distance: float | None = None
    sigma_deg: float | None = None
    mount: Plane | None = None
    initial_std: tuple[float, float] | None = None

    @classmethod
    def nominal(cls, plane: Plane, sigma_distance: float | None = None,
                sigma_deg: float | None = None) -> Mounting:
        """``plane`` is the nominal mount (``ground.nominal: true``): frame 0's ground is
        known only to the prior's width."""
        sigmas = default_sigmas(plane, sigma_distance, sigma_deg)
        return cls(sigma_distance, sigma_deg, mount=plane, initial_std=sigmas)


@dataclass(frozen=True)
class InitialTilt:
    """init.yaml's tilt against the images': ``measured_deg`` (2,) the measured normal's tilt
    angles in the chart of init.yaml's plane, ``std_deg`` (2,) their std, ``chi2`` the
    contradiction's chi-square (2 dof), ``frame`` where measured, ``adopted`` whether the
    measurement corrected the plane."""

    measured_deg: tuple[float, float]
    std_deg: tuple[float, float]
    chi2: float
    frame: int
    adopted: bool

    @property
    def contradicts(self) -> bool:
        """The images contradict init.yaml's tilt (chi-square above CONSISTENT_CHI2)."""
        return self.chi2 >= CONSISTENT_CHI2
