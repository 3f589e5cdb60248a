"""Errors a user can act on.

Every stage raises :class:`InputError` for bad input; the CLI prints its
message as one line and exits with status 2.  Nothing else is caught, so a
programming error still shows its traceback to the developer.
"""


class InputError(Exception):
    """Bad input: the message is one line that names the problem."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))
