"""--config FILE: option values from a YAML file, on the group and on every command.

The file is a YAML mapping of option names (long names without the dashes, ``max-points``
or ``max_points``) to values, for every command that has the option, and of command names
to mappings of that command's own options, which win over the top-level ones::

    overwrite: true        # every command with --overwrite
    threshold: 6.0         # init, track, batch
    track:
      robust: tukey
    overlay:
      fps: 15

The values become the command's click ``default_map``, so the command line wins. A key that
is no option of any command (or, in a command's section, of that command), and a value the
option refuses, is one line naming the file and the key (exit status 2).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from monovo_cli.cli.options import BadInput

#: ``ctx.meta`` key of the --config files given before the command's name (the group's).
_CONFIG_META = "monovo_cli.config"
#: Options a config file cannot set.
_NOT_IN_CONFIG = ("help", "version", "config")


def _config_keys(command: click.Command) -> dict[str, click.Option]:
    """The keys a config file may give for ``command``: its options' long names without the
    dashes (``max-points``; ``max_points`` is read the same), -> the option."""
    keys = {}
    for p in command.params:
        if not isinstance(p, click.Option):
            continue
        for opt in (*p.opts, *p.secondary_opts):
            if opt.startswith("--") and opt[2:] not in _NOT_IN_CONFIG:
                keys[opt[2:]] = p
    return keys


def _config_value(option: click.Option, value: Any) -> Any:
    """A YAML value as the option's default_map entry (what click then converts as it would
    the command line's text); ``None`` for "not given"."""
    if value is None:
        return None
    if option.is_flag and not option.secondary_opts:
        if not isinstance(value, bool):
            raise click.BadParameter(f"expected true or false, got {value!r}")
        # click >= 8.3 leaves flag_value unset on a plain flag and says its value here
        on = getattr(option, "flag_activation_value", option.flag_value)
        return on if value else None
    if isinstance(value, (list, tuple)) and option.nargs == 1 and not option.multiple:
        value = ",".join(str(v) for v in value)  # --triangle, --max-step as YAML lists
    if isinstance(option.type, (click.Path, click.types.StringParamType)) \
            and not isinstance(value, (str, bool)):
        value = str(value)
    return value


def _read_config(path: Path) -> dict[str, Any]:
    """The mapping of a config file; ConfigError (one line) when it is not one."""
    from monovo_cli.io.yaml_fields import fail, read_yaml, show

    path = Path(path)
    if path.is_dir():
        raise fail(str(path), "is a directory; expected a YAML config file")
    data = read_yaml(path, str(path), "the config file")
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise fail(str(path), f"expected a mapping of option names to values, got {show(data)}")
    return data


def config_defaults(ctx: click.Context, path: Path) -> dict[str, Any]:
    """The ``default_map`` that the config file ``path`` gives ``ctx.command``.

    The file is a YAML mapping of option names (long names without the dashes) to values,
    for every command that has the option, and of command names to mappings of that
    command's options, which win over the top-level ones. A key that is no option of any
    command (or, in a command's section, of that command) is a ConfigError naming the file
    and the key; so is a value that the option refuses.
    """
    from monovo_cli.io.yaml_fields import check_keys, fail, show

    name = str(path)
    data = _read_config(path)
    root = ctx.find_root().command
    commands = dict(root.commands) if isinstance(root, click.Group) else {}
    command_name = ctx.command.name
    commands.setdefault(command_name, ctx.command)
    every = sorted({k.replace("_", "-") for c in commands.values() for k in _config_keys(c)})
    sections = {k for k, v in data.items() if k in commands}
    top = {k: v for k, v in data.items() if k not in sections}
    check_keys(name, {str(k).replace("_", "-"): v for k, v in top.items()},
               tuple(every) + tuple(sorted(commands)), "")
    for section in sections:
        if not isinstance(data[section], dict):
            raise fail(name, f"{section}: expected a mapping of 'monovo {section}' options, "
                             f"got {show(data[section])}")
        own = tuple(sorted(_config_keys(commands[section])))
        check_keys(name, {str(k).replace("_", "-"): v for k, v in data[section].items()}, own,
                   f"{section}.")
    keys = _config_keys(ctx.command)
    chosen: dict[str, tuple[str, Any]] = {}
    for where, entries in (("", top), (f"{command_name}.", data.get(command_name) or {})):
        for key, value in entries.items():
            key = str(key).replace("_", "-")
            if key in keys:
                chosen[key] = (f"{where}{key}", value)
    defaults: dict[str, Any] = {}
    for key, (shown, value) in chosen.items():
        option = keys[key]
        try:
            value = _config_value(option, value)
            if value is not None:
                option.process_value(ctx, value)  # refused here, not later without the file
        except click.BadParameter as exc:
            raise fail(name, f"{shown}: {exc.message}") from None
        if value is not None:
            defaults[option.name] = value
    return defaults


def _apply_config(ctx: click.Context, param: click.Parameter, value: Path | None) -> None:
    """--config: before the command's name, remembered for the command; after it (and for
    the one given before), the file's values become the command's defaults (``default_map``),
    so that the command line wins. Its problems are one line, exit status 2."""
    from monovo_cli.errors import MonovoError

    if isinstance(ctx.command, click.Group):
        if value is not None:
            ctx.meta.setdefault(_CONFIG_META, []).append(value)
        return
    paths = [*ctx.meta.get(_CONFIG_META, []), *([value] if value is not None else [])]
    defaults = dict(ctx.default_map or {})
    try:
        for path in paths:
            defaults.update(config_defaults(ctx, path))
    except MonovoError as exc:
        raise BadInput(str(exc)) from None
    ctx.default_map = defaults


def config_option(f):
    """--config FILE, on the group and on every command (see :func:`config_defaults`)."""
    return click.option("--config", type=click.Path(path_type=Path), default=None,
                        is_eager=True, expose_value=False, callback=_apply_config,
                        metavar="FILE",
                        help="A YAML file of option values (monovo.yaml); the command "
                             "line wins.")(f)
