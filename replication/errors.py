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
