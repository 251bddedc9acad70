"""Obstacle maps: the field, its static obstacle polygons, a generator and the map text format.

One module per job, every public name re-exported here (``from aoass_env.maps import ...``):

* :mod:`~aoass_env.maps.obstacle_map`: :class:`ObstacleMap`, a rectangular field
  ``[0, width] x [0, height]`` (m) with simple polygons (possibly concave, no holes) as static
  obstacles, stored counter-clockwise without a repeated closing vertex (as RVO2 and pymunk
  expect); :class:`MapError`;
* :mod:`~aoass_env.maps.generator`: :func:`generate_map`, random obstacles at an exact density,
  free space kept connected and passable;
* :mod:`~aoass_env.maps.text_format`: the IMR-CIIRC planning-map text format, :func:`read_map`,
  :func:`write_map`, :class:`MapFormatError`;
* :mod:`~aoass_env.maps.registry`: the maps shipped in the repository's ``maps/`` folder,
  :func:`list_maps`, :func:`load_map`, :func:`validation_split`.

The algorithm and the guarantees are described in ``docs/maps.md``.
"""

from aoass_env.maps.generator import DENSITY_TOL, GRID, MAX_DENSITY, generate_map
from aoass_env.maps.obstacle_map import MapError, ObstacleMap
from aoass_env.maps.registry import MAPS_DIR, SPLITS, list_maps, load_map, validation_split
from aoass_env.maps.text_format import MapFormatError, read_map, write_map

__all__ = [
    "DENSITY_TOL", "GRID", "MAPS_DIR", "MAX_DENSITY", "SPLITS", "MapError", "MapFormatError",
    "ObstacleMap", "generate_map", "list_maps", "load_map", "read_map", "validation_split",
    "write_map",
]
