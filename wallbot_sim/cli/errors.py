"""Errors a subcommand reports as one line and a non-zero exit."""


class CliError(Exception):
    """A user error: printed as ``wallbot-sim VERB: error: MESSAGE``, exit status ``code``."""

    def __init__(self, message: str, code: int = 2) -> None:
        super().__init__(message)
        self.code = code
