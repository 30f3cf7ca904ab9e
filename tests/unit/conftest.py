"""Shared fixtures of the unit tests."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from kernel_scene import SMALL_SCENE

_PREAMBLE = """
import numpy as np, numba, roughvib
from roughvib.model import kernels as kn
from roughvib.model import krylov
from roughvib.model.system import assemble
assert numba.config.DISABLE_JIT, "NUMBA_DISABLE_JIT was not honoured"
s = assemble(roughvib.load_scene("paper-handset", {scene!r}))
inp = dict(np.load({inputs!r}))
out = {{}}
"""


@pytest.fixture
def run_without_jit(tmp_path):
    """Run kernel code in a fresh interpreter with ``NUMBA_DISABLE_JIT=1`` (plain Python).

    Returns a function ``run(body, **arrays) -> dict`` whose ``body`` sees ``s`` (the assembled
    :data:`SMALL_SCENE` system), ``kn``, ``krylov``, ``np`` and ``inp`` (the ``arrays``), and
    fills the dict ``out`` with the arrays to return.
    """

    def run(body: str, **arrays: np.ndarray) -> dict[str, np.ndarray]:
        inputs, outputs = tmp_path / "nojit_in.npz", tmp_path / "nojit_out.npz"
        np.savez(inputs, **arrays)
        code = (_PREAMBLE.format(scene=SMALL_SCENE, inputs=str(inputs))
                + textwrap.dedent(body) + f"\nnp.savez({str(outputs)!r}, **out)\n")
        env = dict(os.environ, NUMBA_DISABLE_JIT="1")
        subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=300)
        with np.load(outputs) as f:
            return {k: f[k] for k in f.files}

    return run
