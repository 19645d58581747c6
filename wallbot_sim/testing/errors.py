"""Errors of controller testing (one-line messages; the command line maps them to exit status 2)."""


class SpecError(Exception):
    """A test spec, or a fault or expectation given to the fixture, that cannot be run: what is wrong, in one line."""


class ControllerWouldNotStart(Exception):
    """The controller under test could not be started, or exited before the run began (its status and log named)."""
