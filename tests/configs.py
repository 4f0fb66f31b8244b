"""Configuration texts shared by the tests of the schema and of the command line."""


def small_rod(*, model: str = "", parareal: str = "", rest: str = "") -> str:
    """A small valid rod problem (21 nodes, T = 2e-3, 4 slices, Lagrange + Richardson coarse
    solver); ``model`` and ``parareal`` add lines to those tables, ``rest`` adds tables."""
    return f"""
[model]
kind = "rod"
n_points = 21
length = 4.0
{model}
[time]
t1 = 0.002
[fine]
dt = 1e-6
[coarse]
dt_ratio = 10
lagrange = {{ epsilon = [5.6, 5.65] }}
richardson = {{ m = 1, r = 0.83 }}
[parareal]
n_slices = 4
{parareal}
{rest}"""


#: The solver tables of a tiny serial run, to follow a ``[model]`` or ``[[bodies]]`` text.
SERIAL_SOLVERS = """
[time]
t1 = 0.1
[fine]
dt = 0.01
[coarse]
dt_ratio = 2
[parareal]
n_slices = 2
[execution]
executor = "serial"
"""
