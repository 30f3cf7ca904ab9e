"""The variables of a run, declared once: name, unit and description of each, and the column
of each output in a row that the solvers fill.

Three kinds, in the order of a result's variables:

- ``OUTPUTS``: one column each, at the positions ``OUT_*`` (the position of the name in
  ``OUTPUTS``);
- ``CONTACT_OUTPUTS``: a block of K columns each (contact-major blocks after the fixed
  columns), found with ``kernels.out_force_column`` / ``out_roughness_column``;
- ``EVENT_LOG_VARIABLES``: no column; rebuilt on the output grid from the event log when a
  result is built (``roughvib.simulation``).

Every solver writes a row through one function, ``kernels.write_output_row``, whose
arguments are the outputs by name; :data:`roughvib.results.VARIABLES` (the units and long
names of a result's Dataset) is this table. A new output is one entry here and one argument
of ``write_output_row`` (and its value in each solver that calls it).

Plain Python, no numpy or numba: ``roughvib.results`` imports it, and reading a result
must not import the solver stack.
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["CONTACT_OUTPUTS", "EVENT_LOG_VARIABLES", "N_OUT_FIXED", "OUTPUTS", "OUT_NAMES",
           "VARIABLE_TABLE", "Variable", "contact_column", "n_output_columns", "output_columns"]


class Variable(NamedTuple):
    """One variable of a run.

    Attributes
    ----------
    name : str
        The variable's name in a result (``result.nc``) and in the code.
    unit : str
        Its unit (UDUNITS notation: ``"m s-1"``; ``"1"`` for a ratio or a flag).
    description : str
        Its long name in a result: what it is, and its sign convention.
    """

    name: str
    unit: str
    description: str


#: the fixed outputs, one column each, in column order
OUTPUTS = (
    Variable("block_vertical_displacement", "m", "vertical block displacement (positive down)"),
    Variable("block_vertical_velocity", "m s-1", "vertical block velocity (positive down)"),
    Variable("block_vertical_acceleration", "m s-2",
             "vertical block acceleration (positive down)"),
    Variable("plate_vertical_acceleration", "m s-2",
             "plate acceleration at the observation point (positive down)"),
    Variable("block_tangential_displacement", "m", "tangential block displacement"),
    Variable("block_tangential_velocity", "m s-1",
             "tangential block velocity (friction velocity)"),
    Variable("friction_force", "N", "friction force on the block (opposing +velocity)"),
    Variable("normal_force", "N", "total normal contact force"),
    Variable("friction_coefficient", "1", "friction force / normal force"),
)
#: the outputs per contact after the fixed ones, each a block of K columns
CONTACT_OUTPUTS = (
    Variable("contact_force", "N", "normal force per contact spring"),
    Variable("roughness_input", "m", "roughness displacement input per contact (positive down)"),
)
#: the variables rebuilt from the event log on the output grid (no output column)
EVENT_LOG_VARIABLES = (
    Variable("contact_closed", "1",
             "contact closed (1) or open, lifted off (0), from the event log"),
    Variable("stick", "1", "block in a stick phase (1) or sliding (0), from the event log"),
)
#: every variable of a run, in the order of a result's variables
VARIABLE_TABLE = OUTPUTS + CONTACT_OUTPUTS + EVENT_LOG_VARIABLES

OUT_NAMES = tuple(v.name for v in OUTPUTS)
N_OUT_FIXED = len(OUTPUTS)

# the column of each fixed output: its position in OUTPUTS, by name
OUT_Z = OUT_NAMES.index("block_vertical_displacement")
OUT_VZ = OUT_NAMES.index("block_vertical_velocity")
OUT_AZ = OUT_NAMES.index("block_vertical_acceleration")
OUT_PLATE_ACC = OUT_NAMES.index("plate_vertical_acceleration")
OUT_X = OUT_NAMES.index("block_tangential_displacement")
OUT_VX = OUT_NAMES.index("block_tangential_velocity")
OUT_FRICTION = OUT_NAMES.index("friction_force")
OUT_NORMAL = OUT_NAMES.index("normal_force")
OUT_MU = OUT_NAMES.index("friction_coefficient")
# the per-contact outputs' blocks, by name: their position in CONTACT_OUTPUTS
OUT_C_FORCE = tuple(v.name for v in CONTACT_OUTPUTS).index("contact_force")
OUT_C_ROUGHNESS = tuple(v.name for v in CONTACT_OUTPUTS).index("roughness_input")


def contact_column(block, k, K):
    """The column of contact k's value in the per-contact block ``block`` (``OUT_C_*``).

    The one formula of a per-contact column; the kernels compile it (``out_force_column``,
    ``out_roughness_column``).

    Parameters
    ----------
    block : int
        The output's position in ``CONTACT_OUTPUTS`` (``OUT_C_*``).
    k, K : int
        The contact and the number of contacts.

    Returns
    -------
    int
        The column in an output row.
    """
    return N_OUT_FIXED + block * K + k


def n_output_columns(K: int) -> int:
    """Number of output columns with K contacts: the fixed ones, then K per contact output.

    Parameters
    ----------
    K : int
        Number of contacts.

    Returns
    -------
    int
        The width of an output row.
    """
    return N_OUT_FIXED + len(CONTACT_OUTPUTS) * K


def output_columns(K: int) -> dict[str, int | slice]:
    """Where each output lies in a row with K contacts.

    Parameters
    ----------
    K : int
        Number of contacts.

    Returns
    -------
    dict
        Name -> column (fixed outputs) or slice of K columns (per-contact outputs), in the
        order of ``OUTPUTS`` then ``CONTACT_OUTPUTS``.
    """
    cols: dict[str, int | slice] = {v.name: j for j, v in enumerate(OUTPUTS)}
    for j, v in enumerate(CONTACT_OUTPUTS):
        start = contact_column(j, 0, K)
        cols[v.name] = slice(start, start + K)
    return cols
