"""Coverage maps: detection probability around the vehicle at points and on grids."""

from sensorgap.coverage.grid import GridCoverage, GridSpec, evaluate_grid
from sensorgap.coverage.points import PointCoverage, evaluate_points
from sensorgap.coverage.scene import Scene

__all__ = [
    "GridCoverage",
    "GridSpec",
    "PointCoverage",
    "Scene",
    "evaluate_grid",
    "evaluate_points",
]
