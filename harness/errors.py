"""The one exception type the command line reports as a one-line message."""


class HarnessError(Exception):
    """A user error or a failed run: reported without a traceback, exit code 2."""
