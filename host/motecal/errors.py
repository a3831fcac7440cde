"""Errors a user can cause.  The CLI prints them as one line and exits non-zero."""


class UserError(Exception):
    """Bad input from the user: arguments, files, databases, sessions.

    ``str(err)`` is the one line shown on stderr; ``exit_code`` is the status.
    """

    exit_code = 2

    def __init__(self, message: str, exit_code: int | None = None):
        super().__init__(message)
        if exit_code is not None:
            self.exit_code = exit_code


class QualityError(UserError):
    """Data that cannot give a trustworthy result (refused unless --force)."""

    exit_code = 3
