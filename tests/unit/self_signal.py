"""A ``roughvib`` command that sends itself a signal at a chosen point of its work.

A test of Ctrl-C, SIGTERM or SIGKILL must land the signal where it means to: in the
integration, just after a checkpoint, between the cases of a sweep. A test that waits on the
wall clock for the work to be still running (a checkpoint appeared, a case finished, a progress
line came) races the solver: it breaks when the solver or the machine gets faster. Here the
command's own process sends the signal from a hook that the work itself calls, so the signal
lands at the same point of the work on any machine.
"""

import subprocess
import sys
import textwrap

from terminal import sigint_as_on_a_terminal

#: the child: argv is the signal's name, "self" or "group", the point, the count, then the
#: arguments of ``roughvib``. The points:
#:
#: - "progress": the count-th time the solver reports its progress before the end of the run
#:   (after a chunk of steps, in the integration);
#: - "case": the count-th time a progress indicator counts one unit of work done (in a sweep: a
#:   case has ended and its directory is in place);
#: - "checkpoint": just after the count-th checkpoint is in place;
#: - "checkpoint-rename": the count-th checkpoint written to its temporary file, before it
#:   replaces the previous one.
_CHILD = textwrap.dedent("""
    import os, signal, sys
    from roughvib import _progress
    from roughvib.cli import main
    from roughvib.solvers import adaptive_modal, checkpoint, ida

    sig, target, where, count = (signal.Signals[sys.argv[1]], sys.argv[2], sys.argv[3],
                                 int(sys.argv[4]))
    calls = []

    def stop():
        calls.append(1)
        if len(calls) == count:
            if target == "group":  # as Ctrl-C in a terminal: the command and its workers
                os.killpg(os.getpgrp(), sig)
            else:
                os.kill(os.getpid(), sig)

    def on_progress(cls):
        real = cls.refresh

        def refresh(self):
            real(self)
            if 0 < self.n < self.total:
                stop()
        cls.refresh = refresh

    def on_update(cls):
        real = cls.update

        def update(self, n=1):
            real(self, n)
            stop()
        cls.update = update

    def after_checkpoint(module):
        real = module.write_checkpoint

        def write(directory, cp):
            path = real(directory, cp)
            stop()
            return path
        module.write_checkpoint = write

    class BeforeRename:  # the checkpoint module's view of os
        def __getattr__(self, name):
            return getattr(os, name)

        def replace(self, src, dst):
            stop()
            return os.replace(src, dst)

    if where in ("progress", "case"):
        for cls in (_progress.LineProgress, _progress.NoProgress):
            (on_progress if where == "progress" else on_update)(cls)
    elif where == "checkpoint":
        after_checkpoint(adaptive_modal)
        after_checkpoint(ida)
    elif where == "checkpoint-rename":
        checkpoint.os = BeforeRename()
    else:
        raise SystemExit(f"unknown point {where!r}")
    status = main(sys.argv[5:])
    if len(calls) < count:
        print(f"roughvib ended without the signal: its work passed {where!r} {len(calls)} "
              f"of {count} times", file=sys.stderr)
    sys.exit(status)
""")


def start_stopping_itself(sig, where: str, count: int, *argv: str, group: bool = False,
                          **popen) -> subprocess.Popen:
    """Start ``roughvib *argv`` in a child process that sends ``sig`` to itself (or, with
    ``group``, to its process group: start it with ``start_new_session=True``) at the
    ``count``-th time its work passes ``where`` (see :data:`_CHILD`).

    SIGINT is at its default in the child, as for a command run in a terminal. stderr is a
    pipe (text) unless ``popen`` says otherwise.
    """
    popen.setdefault("stderr", subprocess.PIPE)
    return subprocess.Popen([sys.executable, "-c", _CHILD, sig.name,
                             "group" if group else "self", where, str(count), *argv],
                            text=True, preexec_fn=sigint_as_on_a_terminal, **popen)
