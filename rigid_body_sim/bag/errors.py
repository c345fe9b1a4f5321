"""The one exception type the bag tools raise for bad input; its text is the user message."""
import re


class BagError(Exception):
    """A bag cannot be written or read; ``str(err)`` is a complete one-line explanation."""


def recover_hint(path: str) -> str:
    """The command that rebuilds an indexed bag from an unfinished one, spelled for this
    setup (see ``rigid_body_sim.cli_command``)."""
    from .. import cli_command
    out = re.sub(r'(\.mcap)?$', '_recovered.mcap', path.rstrip('/'), count=1) \
        if path.endswith('.mcap') else path.rstrip('/') + '_recovered'
    return f'{cli_command()} bag recover {path} {out}'
