"""The ``monovo`` command line: parse, set up logging and progress, one library call per command.

:mod:`~monovo_cli.cli.group` holds the group (-q/-v, errors to exit statuses, logging,
signals, the progress bar), :mod:`~monovo_cli.cli.options` the options several commands
share, each declared once, :mod:`~monovo_cli.cli.config` ``--config FILE`` (option values
from YAML, for every command), and each command has its own module. A command imports the
library (numpy, OpenCV, the pipeline) when it runs, looking its function up then, so that
``monovo --help`` starts at once.
"""

from monovo_cli.cli import batch, evaluate, init, overlay, synth, track
from monovo_cli.cli.group import main

for _command in (synth.synth, init.init, track.track, overlay.overlay, evaluate.eval_,
                 batch.batch):
    main.add_command(_command)

__all__ = ["main"]
