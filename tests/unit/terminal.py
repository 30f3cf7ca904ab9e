"""How the tests start a command that must see Ctrl-C as it would in a terminal."""

import signal


def sigint_as_on_a_terminal():
    """In the child before exec: SIGINT at its default, as for a command run in the foreground.

    A process started in the background by a non-interactive shell (``pytest ... &``, some CI
    runners) inherits SIGINT ignored, and Python then leaves it ignored (the Unix convention
    for background jobs, which roughvib keeps); the tests of Ctrl-C must not depend on how the
    test run itself was started."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
