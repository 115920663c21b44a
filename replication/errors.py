"""The one exception type the command line turns into a one-line message."""


class InputError(ValueError):
    """Bad data or a bad config value.

    The message is one line naming the file or setting, what was found and what was
    expected; ``replicate`` prints it to stderr and exits with status 2.
    """


def check(condition, message):
    """Raise :class:`InputError` with ``message`` unless ``condition`` holds.

    Parameters
    ----------
    condition : bool
    message : str
        One line: the setting or file, what was found, what was expected.
    """
    if not condition:
        raise InputError(message)


def one_line_error(message):
    """An ``argparse`` parser's ``error``: its refusal as one ``error:`` line and exit
    status 2 (argparse prints its usage first). ``parser.error = one_line_error``."""
    import sys

    print(f"error: {message}", file=sys.stderr)
    raise SystemExit(2)
