"""carat: sparse nonlinear least squares with exact residual-block compression.

numpy in, numpy out. Poses are 4 x 4 float64 arrays T_target_source / T_world_frame (metres),
trajectories N x 4 x 4, point clouds N x 3 arrays (metres). carat's errors are raised as
carat.Error (a RuntimeError) with carat's one-line message; wrong types and shapes as TypeError
or ValueError naming the argument. Long calls release the GIL and stop early on Ctrl-C.
"""

from ._carat import *  # noqa: F401,F403
from ._carat import __version__, Error  # noqa: F401
