"""The one exception root of monovo.

Everything the user can fix (a bad file, a bad option, an impossible geometry)
raises a subclass of :class:`MonovoError`; the CLI turns it into one line on
stderr and exit status 2. Anything else is a bug and exits 1.
"""


class MonovoError(Exception):
    """Base class of every error the user can act on."""


class ConfigError(MonovoError):
    """init.yaml / camera_info is malformed or describes an impossible setup."""


class InputError(MonovoError):
    """A sequence, frame, CSV or TUM file cannot be used."""


class OutputError(MonovoError):
    """An output location cannot be written."""


class TrackingError(MonovoError):
    """The ground model cannot be built (e.g. too few observation points)."""
