"""The pymunk world: anchor dynamics, static and moving obstacles, range sensing, contacts.

Frame and units: world frame in metres, x to the right, y up, the field is
``[0, width] x [0, height]`` of the :class:`~aoass_env.maps.ObstacleMap`; angles in radians,
counter-clockwise from +x, wrapped to ``(-pi, pi]``; time in seconds. docs/world.md describes the
model (dynamics, moving obstacles, sensing, contact semantics) in full.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pymunk
import shapely

from aoass_env.clearance import MARGIN, ClearanceCertificates
from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.rays import StaticShapes, cast_rays, compiled_rays
from aoass_env.trig import SCALAR_TRIG
from aoass_env.validators import real, vec2

# Collision types (pymunk handlers) and filter categories (queries) of the four kinds of shape.
_ANCHOR, _STATIC, _WALL, _MOVING = 1, 2, 3, 4
_CAT_ANCHOR, _CAT_STATIC, _CAT_WALL, _CAT_MOVING = 1, 2, 4, 8
_SENSED = pymunk.ShapeFilter(mask=_CAT_STATIC | _CAT_WALL | _CAT_MOVING)
_STATIC_ONLY = pymunk.ShapeFilter(mask=_CAT_STATIC | _CAT_WALL)

# The hot paths (substep loop, rays, d_obs) call Chipmunk2D's C API through pymunk's low-level
# access (``pymunk.cp``, ``pymunk.ffi``) with reused query buffers: pymunk's wrappers cost
# several times the query itself. Same C calls with the same arguments: same results.
_cp, _ffi = pymunk.cp, pymunk.ffi
_SENSED_PTR = _ffi.new("cpShapeFilter *", tuple(_SENSED))
_STATIC_ONLY_PTR = _ffi.new("cpShapeFilter *", tuple(_STATIC_ONLY))
_SENSED_C, _STATIC_ONLY_C = _SENSED_PTR[0], _STATIC_ONLY_PTR[0]


def _sets_velocity_to_gravity(func: Any) -> bool:
    """Does the velocity function ``func`` set a body's velocity to the gravity, exactly?"""
    space, body = pymunk.Space(), pymunk.Body(1.0, math.inf)
    space.add(body, pymunk.Circle(body, 0.5))
    _cp.cpBodySetVelocityUpdateFunc(body._body, func)
    command = (0.1 + 2.0**-40, -3.0 - 2.0**-40)
    _cp.cpSpaceSetGravity(space._space, command)
    _cp.cpSpaceStep(space._space, 0.1)
    v = _cp.cpBodyGetVelocity(body._body)
    return (v.x, v.y) == command


@_ffi.callback("cpBodyVelocityFunc")
def _velocity_from_gravity_py(body: Any, gravity: Any, damping: float, dt: float) -> None:
    """:data:`_VELOCITY_FROM_GRAVITY` as a Python callback, where the C form fails its probe."""
    _cp.cpBodySetVelocity(body, gravity)


def _velocity_from_gravity() -> Any:
    """The anchor's velocity function, which sets its velocity to the space's gravity.

    The anchor is the space's only dynamic body (the moving obstacles are kinematic, and
    Chipmunk's default velocity function skips those), so the gravity is free to carry the
    velocity command of the coming substep; :meth:`World.advance` sets it before each step.
    Chipmunk calls a velocity function as ``f(body, gravity, damping, dt)``; its own
    ``cpBodySetVelocity(body, v)`` takes the first two arguments and ignores the other two
    (caller-cleaned arguments, as on the ABIs Chipmunk runs on), so it serves as that function
    in C, without a Python callback at every substep. A probe space checks that it sets the
    velocity to the gravity exactly; where it does not, a Python callback makes the same call.
    """
    in_c = _ffi.cast("cpBodyVelocityFunc", _ffi.addressof(_cp, "cpBodySetVelocity"))
    return in_c if _sets_velocity_to_gravity(in_c) else _velocity_from_gravity_py


_VELOCITY_FROM_GRAVITY = _velocity_from_gravity()

_SLOP_FRACTION = 0.01   # allowed anchor overlap (pymunk collision_slop) / anchor radius
_APPROACH_TOL = 1e-6    # a touched shape stops a disc moving into it faster than this * speed
_TOUCH_TOL = 1e-9      # a swept disc starting this near (m) a shape touches it (_shape_hit)
_MAX_BOUNCES = 4        # reflections of one moving obstacle within one physics substep
_MAX_SLIDES = 2         # faces the anchor's move slides along within one physics substep
_SPAWN_TRIES = 1000     # random candidates per moving obstacle before giving up
_SKIP_MARGIN = MARGIN   # slack (m) of the proofs that a skipped query would have missed
_CERT_REACH = 4.0       # farthest clearance (m) a certificate measures (nearest-shape query)
_TWO_PI = 2.0 * math.pi


def wrap_angle(angle: float | np.ndarray) -> float | np.ndarray:
    """Angle(s) (rad) wrapped to ``(-pi, pi]``."""
    return math.pi - (math.pi - angle) % (2.0 * math.pi)


def _obstacle_ids(obstacle_map: ObstacleMap) -> np.ndarray:
    """Obstacle index of every convex part: parts of one connected obstacle share an index.

    Obstacles are the polygons of the obstacle union inside the field (overlapping polygons, or
    polygons sharing a stretch of edge, form one obstacle; two that meet at a single point stay
    two, as shapely's union leaves them); a part wholly outside the field gets its own index.
    """
    parts = obstacle_map.convex_parts
    if not parts:
        return np.zeros(0, dtype=np.int64)
    comps = shapely.get_parts(obstacle_map.union)
    comps = comps[shapely.get_type_id(comps) == shapely.GeometryType.POLYGON]
    # A point strictly inside a part (inside the field) lies inside exactly one component: the
    # vertex mean of a part that lies in the field; a point on the surface of its clipped
    # piece otherwise (shapely, slower).
    counts = np.array([len(p) for p in parts])
    vertices = np.concatenate(parts)
    points = np.add.reduceat(vertices, np.r_[0, np.cumsum(counts)[:-1]]) / counts[:, None]
    in_field = np.logical_and.reduceat(obstacle_map.bounds_contain(vertices),
                                       np.r_[0, np.cumsum(counts)[:-1]])
    points = shapely.points(points)
    out = np.flatnonzero(~in_field)
    if len(out):
        points[out] = shapely.point_on_surface(shapely.intersection(
            np.array([shapely.Polygon(parts[i]) for i in out]), obstacle_map.field_polygon))
    part_i, comp_i = shapely.STRtree(comps).query(points, predicate="intersects")
    ids = np.full(len(parts), -1, dtype=np.int64)
    ids[part_i[::-1]] = comp_i[::-1]          # the first matching component wins
    outside = ids < 0
    ids[outside] = len(comps) + np.arange(int(outside.sum()))
    return ids


class World:
    """The simulated field: one anchor robot, static obstacles, moving obstacles.

    Args:
        config: simulation parameters (anchor limits, dt, substeps, sensing, moving obstacles).
        obstacle_map: the field and its static obstacles; the field is ``obstacle_map.width``
            x ``obstacle_map.height`` (m).
        rng: the only source of randomness (moving-obstacle spawn, speeds, heading changes);
            the world keeps drawing from it while it steps.
        start: anchor start position (x, y) (m); the anchor disc must lie inside the field and
            must not overlap a static obstacle.
        start_heading: initial heading (rad); the anchor starts at rest.

    Raises:
        TypeError: an argument of the wrong type.
        ValueError: a bad start, or no room to place the moving obstacles.
    """

    def __init__(self, config: AOASSConfig, obstacle_map: ObstacleMap,
                 rng: np.random.Generator, start: tuple[float, float],
                 start_heading: float = 0.0) -> None:
        for name, value, kind in (("config", config, AOASSConfig),
                                  ("obstacle_map", obstacle_map, ObstacleMap),
                                  ("rng", rng, np.random.Generator)):
            if not isinstance(value, kind):
                raise TypeError(f"{name} must be a {kind.__name__}, got {type(value).__name__}")
        self.config = config
        self.obstacle_map = obstacle_map
        self._rng = rng
        self._sdt = config.substep_dt
        self._skin = 0.5 * _SLOP_FRACTION * config.anchor_radius
        # _move_moving's constants: a disc's radius, how far it may meet the anchor (skin
        # inside it), and the centre distance beyond which the two discs cannot meet
        self._r_moving = r_moving = config.moving_obstacle_radius
        self._r_meet = max(r_moving - self._skin, 0.0)
        self._reach_meet = self._r_meet + config.anchor_radius + _SKIP_MARGIN
        self._space = space = pymunk.Space()
        space.collision_slop = _SLOP_FRACTION * config.anchor_radius
        # shape -> (kind, obstacle index); kind is the contact counter the shape belongs to
        self._owner: dict[pymunk.Shape, tuple[str, int]] = {}
        self._add_walls()
        self._add_static_obstacles()

        x0, y0 = self._check_start(start)
        self._heading = wrap_angle(real("start_heading", start_heading, "rad"))
        self._speed = 0.0
        self._anchor = pymunk.Body(1.0, math.inf)
        self._anchor.position = (x0, y0)
        self._anchor_disc = disc = pymunk.Circle(self._anchor, config.anchor_radius)
        disc.friction, disc.elasticity = 0.0, 0.0
        disc.collision_type = _ANCHOR
        disc.filter = pymunk.ShapeFilter(categories=_CAT_ANCHOR)
        space.add(self._anchor, disc)

        self._spawn_moving((x0, y0))
        self._bind_chipmunk()
        # slot 0: the anchor, slot 1 + i: moving obstacle i
        self._clearance = ClearanceCertificates(self._static_distance, 1 + len(self._mbodies))

        self._touching: dict[tuple[str, int], int] = {}  # touching parts per obstacle
        self._released_at: dict[tuple[str, int], int] = {}  # substep an obstacle was let go
        self._contacts = {"static": 0, "wall": 0, "moving": 0}
        space.on_collision(_ANCHOR, _STATIC, begin=self._begin, separate=self._separate)
        space.on_collision(_ANCHOR, _WALL, begin=self._begin, separate=self._separate)
        space.on_collision(_ANCHOR, _MOVING, begin=self._begin, pre_solve=self._bounce_off_anchor,
                           separate=self._separate)
        self._substeps_done = 0
        self._xy: np.ndarray | None = None    # position's array, until the anchor moves
        self._ray_offsets = 2.0 * math.pi * np.arange(config.n_rays) / config.n_rays
        # the static shapes as the compiled rays read them, where those give Chipmunk's floats
        self._ray_shapes = self._static_shapes() if compiled_rays() else None

    # Chipmunk handles and query buffers (cffi objects): not picklable, rebuilt from the pymunk
    # objects, which pymunk pickles itself
    _C_FIELDS = ("_c_space", "_c_anchor", "_c_disc", "_c_moving", "_seg_info", "_point_info")

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        for name in self._C_FIELDS:
            del state[name]
        state["_xy"] = None          # built again, read-only, on the first read
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._bind_chipmunk()
        # pymunk does not pickle the space's arbiters: every contact in progress begins again
        # at the copy's next substep. Counted as touching, it never separated in the copy (the
        # obstacle's later contacts went uncounted); as a fresh begin it would count twice. So
        # the copy starts untouched with those obstacles let go now: the begin is not a new
        # contact, and a contact that ends instead leaves the state the original reaches.
        for key, touching in self._touching.items():
            if touching:
                self._touching[key] = 0
                self._released_at[key] = self._substeps_done

    def _bind_chipmunk(self) -> None:
        """The Chipmunk handles of the space, the anchor and the moving obstacles, and fresh
        query buffers."""
        self._c_space = self._space._space
        self._c_anchor, self._c_disc = self._anchor._body, self._anchor_disc._shape
        self._c_moving = [body._body for body in self._mbodies]
        # the velocity phase of a substep: the command, carried by the gravity (advance)
        _cp.cpBodySetVelocityUpdateFunc(self._c_anchor, _VELOCITY_FROM_GRAVITY)
        self._seg_info = _ffi.new("cpSegmentQueryInfo *")
        self._point_info = _ffi.new("cpPointQueryInfo *")

    # --- construction ---------------------------------------------------------------------
    def _add_walls(self) -> None:
        """The field border: four static boxes outside the field, one obstacle for contacts."""
        w, h = self.obstacle_map.width, self.obstacle_map.height
        t = max(w, h)   # thick enough that nothing can tunnel through
        boxes = ((-t, -t, w + t, 0.0), (-t, h, w + t, h + t),
                 (-t, 0.0, 0.0, h), (w, 0.0, w + t, h))
        for x0, y0, x1, y1 in boxes:
            shape = pymunk.Poly(self._space.static_body, [(x0, y0), (x1, y0), (x1, y1), (x0, y1)])
            self._add_static(shape, _WALL, _CAT_WALL, ("wall", 0))

    def _add_static_obstacles(self) -> None:
        ids = _obstacle_ids(self.obstacle_map)
        for part, k in zip(self.obstacle_map.convex_parts, ids.tolist(), strict=True):
            shape = pymunk.Poly(self._space.static_body, part.tolist())
            self._add_static(shape, _STATIC, _CAT_STATIC, ("static", k))

    def _static_shapes(self) -> StaticShapes:
        """The walls and static parts as Chipmunk holds them (:class:`~aoass_env.rays.
        StaticShapes`), read once per map: they depend on the map alone."""
        return self.obstacle_map.derived(("static shapes",), lambda: StaticShapes.of(
            shape for shape in self._owner if shape.body is self._space.static_body))

    def _add_static(self, shape: pymunk.Shape, ctype: int, category: int,
                    owner: tuple[str, int]) -> None:
        shape.collision_type = ctype
        shape.filter = pymunk.ShapeFilter(categories=category)
        shape.friction, shape.elasticity = 0.0, 0.0
        self._owner[shape] = owner
        self._space.add(shape)

    def _check_start(self, start: Any) -> tuple[float, float]:
        xy = np.array(vec2("start", start, "m"))
        r = self.config.anchor_radius
        m = self.obstacle_map
        if not m.bounds_contain(xy, margin=r)[0]:
            raise ValueError(
                f"start={tuple(xy.tolist())}: the anchor (radius {r} m) must lie inside the "
                f"field, i.e. x in [{r}, {m.width - r}] and y in [{r}, {m.height - r}] m")
        hit = self._space.point_query_nearest(tuple(xy.tolist()), r, _STATIC_ONLY)
        if hit is not None:
            raise ValueError(
                f"start={tuple(xy.tolist())}: the anchor (radius {r} m) overlaps a static "
                f"obstacle: its centre is {hit.distance:.3g} m from the obstacle's surface "
                f"(negative: inside), it must be at least {r} m")
        return float(xy[0]), float(xy[1])

    def _spawn_moving(self, anchor_start: tuple[float, float]) -> None:
        """Place the moving obstacles at random in free space (rejection sampling).

        Every obstacle keeps a gap of one obstacle radius from static obstacles, walls, the
        other moving obstacles and the anchor at its start.
        """
        cfg, rng = self.config, self._rng
        n, r = cfg.n_moving_obstacles, cfg.moving_obstacle_radius
        w, h = self.obstacle_map.width, self.obstacle_map.height
        lo = 2.0 * r   # radius + gap
        if n and (w <= 2 * lo or h <= 2 * lo):
            raise ValueError(f"moving_obstacle_radius={r} m is too large for a {w} x {h} m field")
        placed: list[tuple[float, float]] = []
        for i in range(n):
            for _ in range(_SPAWN_TRIES):
                p = tuple(rng.uniform((lo, lo), (w - lo, h - lo)).tolist())
                if self._space.point_query_nearest(p, lo, _STATIC_ONLY) is None \
                        and math.dist(p, anchor_start) >= cfg.anchor_radius + lo \
                        and all(math.dist(p, q) >= 3.0 * r for q in placed):
                    placed.append(p)
                    break
            else:
                raise ValueError(
                    f"could not place moving obstacle {i + 1} of n_moving_obstacles={n} "
                    f"(radius {r} m) in free space after {_SPAWN_TRIES} random tries; use fewer "
                    f"or smaller moving obstacles or a less crowded map")
        lo_v, hi_v = cfg.moving_obstacle_speed
        speed = rng.uniform(lo_v, hi_v, size=n)
        heading = rng.uniform(0.0, 2.0 * math.pi, size=n)
        rate = cfg.moving_obstacle_turn_rate
        next_turn = rng.exponential(1.0 / rate, size=n) if rate > 0 else np.full(n, np.inf)
        # moving-obstacle state as plain floats: the substep loop runs on them
        self._mpos = placed
        self._mspeed: list[float] = speed.tolist()
        self._mvel: list[tuple[float, float]] = list(zip(
            (speed * np.cos(heading)).tolist(), (speed * np.sin(heading)).tolist(), strict=True))
        self._next_turn: list[float] = next_turn.tolist()
        self._turn_due = min(self._next_turn, default=math.inf)   # earliest heading change (s)
        self._mbodies: list[pymunk.Body] = []
        for i, p in enumerate(placed):
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            body.position = p
            disc = pymunk.Circle(body, r)
            disc.friction, disc.elasticity = 0.0, 0.0
            disc.collision_type = _MOVING
            disc.filter = pymunk.ShapeFilter(categories=_CAT_MOVING)
            self._owner[disc] = ("moving", i)
            self._space.add(body, disc)
            self._mbodies.append(body)

    # --- pymunk callbacks -----------------------------------------------------------------
    def _begin(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
        """A part starts touching the anchor: a new contact unless its obstacle is touched
        already or was let go less than one control period ago."""
        key = self._owner[arbiter.shapes[1]]
        touching = self._touching.get(key, 0)
        self._touching[key] = touching + 1
        released = self._released_at.get(key)
        if touching == 0 and (released is None or
                              self._substeps_done - released >= self.config.physics_substeps):
            self._contacts[key[0]] += 1

    def _separate(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
        key = self._owner.get(arbiter.shapes[1])
        if key is None:     # the space is being torn down
            return
        self._touching[key] -= 1
        if self._touching[key] == 0:
            self._released_at[key] = self._substeps_done

    def _bounce_off_anchor(self, arbiter: pymunk.Arbiter, space: pymunk.Space,
                           data: Any) -> None:
        """A moving obstacle touching the anchor reflects its velocity if it moves toward it."""
        shape = arbiter.shapes[1]
        (ax, ay), (mx, my) = self._anchor.position, shape.body.position
        norm = math.hypot(mx - ax, my - ay)
        i = self._owner[shape][1]
        if norm > 0.0:
            self._mvel[i] = _reflect(self._mvel[i], ((mx - ax) / norm, (my - ay) / norm))
        # the solver reads the disc's body velocity, which still holds this substep's approach
        # (its move into the anchor over sdt): it handed that to the anchor, knocking it. The
        # disc's own velocity (reflected, moving off) leaves the anchor to its command.
        _cp.cpBodySetVelocity(self._c_moving[i], self._mvel[i])

    # --- stepping -------------------------------------------------------------------------
    def step(self, speed_cmd: float, heading_cmd: float) -> np.ndarray:
        """Advance one control period ``config.dt`` (s) in ``config.physics_substeps`` steps.

        Args:
            speed_cmd: commanded speed (m/s), clipped to ``[0, anchor_max_speed]``.
            heading_cmd: commanded heading (rad, world frame; any real value).

        Returns:
            (substeps + 1, 3) float64 array of (t [s], x [m], y [m]) of the anchor centre,
            starting with the position before the period.
        """
        return np.array(self.advance(speed_cmd, heading_cmd))

    def advance(self, speed_cmd: float, heading_cmd: float) -> list[tuple[float, float, float]]:
        """:meth:`step`, returning its rows as a list of (t, x, y) tuples of Python floats
        (the simulator's odometer reads them without an array)."""
        cfg, sdt = self.config, self._sdt
        # plain finite floats (the common case) skip the validators' generic checks
        speed_cmd = speed_cmd if type(speed_cmd) is float and math.isfinite(speed_cmd) \
            else real("speed_cmd", speed_cmd, "m/s")
        heading_target = heading_cmd if type(heading_cmd) is float \
            and math.isfinite(heading_cmd) else real("heading_cmd", heading_cmd, "rad")
        target = min(max(speed_cmd, 0.0), cfg.anchor_max_speed)
        max_dv, max_dh = cfg.anchor_max_accel * sdt, cfg.anchor_max_turn_rate * sdt
        get_position, anchor, moving = _cp.cpBodyGetPosition, self._c_anchor, self._c_moving
        set_gravity, space = _cp.cpSpaceSetGravity, self._c_space
        p = get_position(anchor)
        x, y = p.x, p.y
        done = self._substeps_done
        rows = [(done * sdt, x, y)]
        self._xy = None              # the anchor moves: position reads Chipmunk again
        speed, heading = self._speed, self._heading
        for _ in range(cfg.physics_substeps):
            # the bounded command filter: speed toward the target by at most max_dv, heading
            # the shorter way round (counter-clockwise when exactly opposite) by at most max_dh
            speed += min(max(target - speed, -max_dv), max_dv)
            turn = math.pi - (math.pi - (heading_target - heading)) % _TWO_PI
            heading = math.pi - (math.pi - (heading + min(max(turn, -max_dh), max_dh))) % _TWO_PI
            # the velocity phase of the step sets the anchor's velocity to this, before
            # contacts are solved (_velocity_from_gravity)
            set_gravity(space, (speed * math.cos(heading), speed * math.sin(heading)))
            velocity = self._limit_anchor_move(x, y)
            if self._turn_due <= done * sdt:
                self._turn_moving()
            if moving:
                self._move_moving(x, y, velocity)
            _cp.cpSpaceStep(space, sdt)
            done = self._substeps_done = done + 1     # the contact callbacks read it
            self._mpos = [(q.x, q.y) for q in map(get_position, moving)]
            p = get_position(anchor)
            x, y = p.x, p.y
            rows.append((done * sdt, x, y))
        self._speed, self._heading = speed, heading
        self._xy = None
        return rows

    def _turn_moving(self) -> None:
        """Apply the Poisson heading changes that fell due: a new uniform heading, same speed."""
        t, rate, rng = self.time, self.config.moving_obstacle_turn_rate, self._rng
        for i, due in enumerate(self._next_turn):
            if due > t:
                continue
            while due <= t:
                heading = rng.uniform(0.0, 2.0 * math.pi)
                due += rng.exponential(1.0 / rate)
            self._next_turn[i] = due
            speed = self._mspeed[i]
            self._mvel[i] = (speed * math.cos(heading), speed * math.sin(heading))
        self._turn_due = min(self._next_turn)

    def _move_moving(self, ax: float, ay: float, velocity: tuple[float, float]) -> None:
        """Set each moving obstacle's velocity for the coming substep, given the anchor's
        position (ax, ay) (m) and its velocity (m/s) for the substep.

        The disc is swept along its move: it reflects off walls and static obstacles at the
        exact moment of contact and goes on for the rest of the substep; on reaching the anchor
        (where the anchor will be after the substep) it stops ``skin`` inside it, so that pymunk
        registers the contact, and reflects off it. (Once touching, :meth:`_bounce_off_anchor`
        reflects it.) So a moving obstacle never pushes the anchor deeper than ``skin``, and
        cannot squeeze it into a static obstacle. Sweeps that provably touch nothing (clearance
        certificates, distance to the anchor) are skipped: they would return no hit.
        """
        r, sdt, r_meet = self._r_moving, self._sdt, self._r_meet
        reach = self._reach_meet                           # farther: the discs miss
        ox, oy = velocity[0] * sdt, velocity[1] * sdt      # the anchor's coming move
        clear, set_velocity = self._clearance.clear, _cp.cpBodySetVelocity
        for i, body in enumerate(self._c_moving):
            x0, y0 = x, y = self._mpos[i]
            vx, vy = self._mvel[i]
            # free flight, the common case: the whole move provably meets nothing (the first
            # round of the loop below, with neither sweep run; _apart inline)
            move = math.hypot(vx, vy) * sdt
            dx, dy, far = x - ox - ax, y - oy - ay, move + reach
            if dx * dx + dy * dy > far * far and clear(i + 1, x, y, move + r):
                set_velocity(body, ((x + vx * sdt - x0) / sdt, (y + vy * sdt - y0) / sdt))
                continue
            rest = sdt
            for _ in range(_MAX_BOUNCES):
                if rest <= 0.0 or (vx == 0.0 and vy == 0.0):
                    break
                ex, ey = x + vx * rest, y + vy * rest
                move = math.hypot(vx, vy) * rest
                hit = None if clear(i + 1, x, y, move + r) else \
                    self._first_hit((x, y), (ex, ey), r, (vx, vy), _STATIC_ONLY)
                # the anchor disc stays at (ax, ay): the sweep is relative to its coming move
                meet = None if _apart(x - ox - ax, y - oy - ay, move + reach) else \
                    self._shape_hit(self._c_disc, (x - ox, y - oy), (ex - ox, ey - oy), r_meet)
                if meet is not None and _blocks(meet, vx, vy) and \
                        (hit is None or meet[0] < hit[0]):
                    alpha = meet[0]
                    x, y = x + (ex - x) * alpha, y + (ey - y) * alpha
                    vx, vy = _reflect((vx, vy), meet[1:])
                    break
                if hit is None:
                    x, y = ex, ey
                    break
                alpha = hit[0]
                x, y = x + (ex - x) * alpha, y + (ey - y) * alpha
                vx, vy = _reflect((vx, vy), hit[1:])
                rest *= 1.0 - alpha
            self._mvel[i] = (vx, vy)
            set_velocity(body, ((x - x0) / sdt, (y - y0) / sdt))

    def _shape_hit(self, shape: Any, start: tuple[float, float], end: tuple[float, float],
                   radius: float) -> tuple[float, float, float] | None:
        """(alpha, normal x, normal y) where a disc of ``radius`` (m) swept from ``start`` to
        ``end`` (m) first touches the Chipmunk ``shape``, or None.

        A disc starting within ``_TOUCH_TOL`` of the shape (or inside it) touches it at alpha 0,
        the normal pointing out of the shape (the distance's gradient); only a disc clear of it
        is swept. Chipmunk's sweep misses a face the disc starts on (1e-15 m off it, where a
        bounce leaves it) and may return a later face or vertex of the same shape, which let a
        disc turning back into the face pass through it; from inside a shape its normal points
        inward.
        """
        near = self._point_info
        if _cp.cpShapePointQuery(shape, start, near) < radius + _TOUCH_TOL:
            gradient = near.gradient
            return 0.0, gradient.x, gradient.y
        info = self._seg_info
        if _cp.cpShapeSegmentQuery(shape, start, end, radius, info):
            normal = info.normal
            return info.alpha, normal.x, normal.y
        return None

    def _blocking_hits(self, start: tuple[float, float], end: tuple[float, float],
                       radius: float, v: tuple[float, float], shape_filter: pymunk.ShapeFilter,
                       ) -> Iterator[tuple[tuple[float, float, float], Any]]:
        """Each shape that blocks a disc of ``radius`` (m) swept from ``start`` to ``end`` with
        velocity ``v`` (see :func:`_blocks`): its hit (alpha, normal x, normal y) and the
        Chipmunk shape.

        The broadphase of Space.segment_query ignores the radius (Chipmunk2D issue #138), so
        the candidates come from a box query of the swept disc and each is tested exactly.
        """
        (x0, y0), (x1, y1) = start, end
        box = pymunk.BB(min(x0, x1) - radius, min(y0, y1) - radius,
                        max(x0, x1) + radius, max(y0, y1) + radius)
        vx, vy = v
        for shape in self._space.bb_query(box, shape_filter):
            c_shape = shape._shape
            hit = self._shape_hit(c_shape, start, end, radius)
            if _blocks(hit, vx, vy):
                yield hit, c_shape

    def _first_hit(self, start: tuple[float, float], end: tuple[float, float], radius: float,
                   v: tuple[float, float], shape_filter: pymunk.ShapeFilter,
                   ) -> tuple[float, float, float] | None:
        """(alpha, normal x, normal y) of the first of :meth:`_blocking_hits`, or None."""
        best = None
        for hit, _ in self._blocking_hits(start, end, radius, v, shape_filter):
            if best is None or hit[0] < best[0]:
                best = hit
        return best

    def _limit_anchor_move(self, x: float, y: float) -> tuple[float, float]:
        """Stop the anchor's coming move just inside the first shape it would reach; return its
        velocity (m/s) for the substep. (x, y) (m) is its position.

        pymunk detects contacts after moving, so a fast anchor could sink deep into, or tunnel
        through, an obstacle it reaches mid-substep; the move is shortened to end ``skin`` inside
        that shape, and pymunk's solver takes over from the contact. A shape already touched
        stops the anchor only if the solved velocity still points into it (pymunk cannot always
        satisfy a contact with a kinematic moving obstacle and a static one at once, nor two
        static ones in a wedge); then the move slides along that shape's face: its part into the
        shape is cut to what is left of ``skin`` past the anchor's overlap with it (none once the
        overlap is ``skin`` or more), its part along the face is kept, and the slid move is
        checked again against every shape (up to ``_MAX_SLIDES`` faces; pushed into a further
        touched face after that, as in a wedge, the anchor stays). The shortest allowed move
        over every shape it would reach is taken, so its own moves never take it deeper than
        ``skin`` into any. The sweep is skipped when the clearance certificates and the moving
        obstacles' distances prove it free.
        """
        v = _cp.cpBodyGetVelocity(self._c_anchor)
        vx, vy = v.x, v.y
        sdt = self._sdt
        length = math.hypot(vx, vy) * sdt
        if length == 0.0:
            return vx, vy
        r = self.config.anchor_radius
        reach = length + r + self._r_moving + _SKIP_MARGIN
        if self._clearance.clear(0, x, y, length + r):
            reach2 = reach * reach
            for mx, my in self._mpos:
                dx, dy = mx - x, my - y
                if not dx * dx + dy * dy > reach2:         # not _apart(dx, dy, reach)
                    break
            else:
                return vx, vy
        wanted = vx, vy
        for slides in range(_MAX_SLIDES + 1):
            allowed, face = self._anchor_move_limit(x, y, vx, vy, length)
            if face is None:
                break
            if slides == _MAX_SLIDES:
                allowed = 0.0                  # still pushed into a touched face: stay
                break
            nx, ny, excess = face              # slide: the excess inward speed taken off
            vx, vy = vx + excess * nx, vy + excess * ny
            length = math.hypot(vx, vy) * sdt
            if length == 0.0:
                break
        if allowed < length:
            vx, vy = vx * allowed / length, vy * allowed / length
        if (vx, vy) != wanted:
            _cp.cpBodySetVelocity(self._c_anchor, (vx, vy))
        return vx, vy

    def _anchor_move_limit(self, x: float, y: float, vx: float, vy: float, length: float,
                           ) -> tuple[float, tuple[float, float, float] | None]:
        """For the anchor at (x, y) (m) moving with (vx, vy) (m/s), ``length`` (m) in the
        coming substep: the longest move (m) along it that ends at most ``skin`` inside each
        shape it would reach but does not touch yet, and the touched face it pushes deepest
        past its room (what is left of ``skin`` past the anchor's overlap with that shape), as
        (normal x, normal y, excess inward speed in m/s; the normal points out of the shape),
        or None when no touched face is pushed past its room by more than ``_TOUCH_TOL``."""
        r, skin, sdt = self.config.anchor_radius, self._skin, self._sdt
        end = (x + vx * sdt, y + vy * sdt)
        allowed, face, worst = length, None, _TOUCH_TOL / sdt
        for (alpha, nx, ny), shape in self._blocking_hits((x, y), end, r, (vx, vy), _SENSED):
            if alpha > 0.0:
                allowed = min(allowed, alpha * length + skin)
                continue
            # touching: the overlap is r minus the centre's distance to the shape
            overlap = r - _cp.cpShapePointQuery(shape, (x, y), self._point_info)
            excess = -(vx * nx + vy * ny) - max(skin - overlap, 0.0) / sdt
            if excess > worst:
                worst, face = excess, (nx, ny, excess)
        return allowed, face

    def _static_distance(self, x: float, y: float) -> float:
        """Distance (m) from (x, y) (m) to the nearest static obstacle or wall (negative
        inside), or ``_CERT_REACH`` when none is nearer: the clearance certificates' measure."""
        info = self._point_info
        if _cp.cpSpacePointQueryNearest(self._c_space, (x, y), _CERT_REACH, _STATIC_ONLY_C,
                                        info):
            return info.distance
        return _CERT_REACH

    # --- sensing --------------------------------------------------------------------------
    def ray_angles(self) -> np.ndarray:
        """(n_rays,) world-frame angles (rad) of the range-sensor rays; ray 0 is the heading,
        the others follow counter-clockwise at equal spacing."""
        return wrap_angle(self._heading + self._ray_offsets)

    def ray_distances(self) -> np.ndarray:
        """(n_rays,) distances (m) from the anchor centre to the first wall, static or moving
        obstacle along each ray of :meth:`ray_angles`; ``sensing_range`` where none is hit."""
        reach = self.config.sensing_range
        start = _cp.cpBodyGetPosition(self._c_anchor)
        shapes = self._ray_shapes
        if shapes is not None:       # Chipmunk's segment queries, compiled (aoass_env.rays)
            return cast_rays(start.x, start.y, self._heading, self._ray_offsets, reach,
                             shapes.vertices, shapes.normals, shapes.first, shapes.boxes,
                             self.moving_positions, self._r_moving)
        if SCALAR_TRIG:
            # the ray ends of the array code below in Python floats: the same operations
            x, y, h = start.x, start.y, self._heading
            ends = [(x + reach * math.cos(a), y + reach * math.sin(a))
                    for a in [h + offset for offset in self._ray_offsets.tolist()]]
        else:
            angles = self._heading + self._ray_offsets
            ends = zip((start.x + reach * np.cos(angles)).tolist(),
                       (start.y + reach * np.sin(angles)).tolist(), strict=True)
        out = []
        query, space, info = _cp.cpSpaceSegmentQueryFirst, self._c_space, self._seg_info
        for end in ends:
            out.append(info.alpha * reach if query(space, start, end, 0.0, _SENSED_C, info)
                       else reach)
        return np.array(out)

    def nearest_obstacle_distance(self) -> float:
        """d_obs (m): gap between the anchor's surface and the nearest wall, static or moving
        obstacle; 0 while touching, ``sensing_range`` when nothing is closer."""
        r, reach = self.config.anchor_radius, self.config.sensing_range
        info = self._point_info
        if not _cp.cpSpacePointQueryNearest(self._c_space, _cp.cpBodyGetPosition(self._c_anchor),
                                            r + reach, _SENSED_C, info):
            return reach
        return min(max(info.distance - r, 0.0), reach)

    # --- state ----------------------------------------------------------------------------
    @property
    def position(self) -> np.ndarray:
        """Anchor centre (x, y) (m), read-only: one array per position, a new one after each
        step (the step's readers share it)."""
        xy = self._xy
        if xy is None:
            p = _cp.cpBodyGetPosition(self._c_anchor)
            xy = self._xy = np.array((p.x, p.y))
            xy.flags.writeable = False
        return xy

    @property
    def heading(self) -> float:
        """Commanded-filter heading (rad, world frame): the anchor's orientation."""
        return self._heading

    @property
    def speed(self) -> float:
        """Commanded-filter speed (m/s): what the drive asks for, before contacts."""
        return self._speed

    @property
    def velocity(self) -> np.ndarray:
        """Actual anchor velocity (vx, vy) (m/s) after contacts were solved."""
        v = _cp.cpBodyGetVelocity(self._c_anchor)      # what pymunk's Body.velocity reads
        return np.array((v.x, v.y))

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._substeps_done * self._sdt

    @property
    def moving_positions(self) -> np.ndarray:
        """(M, 2) centres of the moving obstacles (m)."""
        return np.array(self._mpos, dtype=np.float64).reshape(-1, 2)

    @property
    def moving_xy(self) -> list[tuple[float, float]]:
        """The centres of :attr:`moving_positions` as (x, y) tuples of Python floats (m), a
        new list."""
        return list(self._mpos)

    @property
    def moving_velocities(self) -> np.ndarray:
        """(M, 2) velocities of the moving obstacles (m/s); a bounce or a random turn changes
        the direction, never the speed."""
        return np.array(self._mvel, dtype=np.float64).reshape(-1, 2)

    @property
    def static_contacts(self) -> int:
        """Touching episodes of the anchor with static obstacles (walls excluded)."""
        return self._contacts["static"]

    @property
    def wall_contacts(self) -> int:
        """Touching episodes of the anchor with the field border."""
        return self._contacts["wall"]

    @property
    def moving_contacts(self) -> int:
        """Touching episodes of the anchor with moving obstacles."""
        return self._contacts["moving"]

    @property
    def contacts(self) -> int:
        """All touching episodes: static + wall + moving."""
        return sum(self._contacts.values())


def _apart(dx: float, dy: float, reach: float) -> bool:
    """Whether the offset (dx, dy) (m) is longer than ``reach`` (m)."""
    return dx * dx + dy * dy > reach * reach


def _blocks(hit: tuple[float, float, float] | None, vx: float, vy: float) -> bool:
    """Whether a swept-disc ``hit`` (alpha, normal x, normal y) stops a disc moving with
    velocity (vx, vy) (m/s).

    A shape the disc already touches at the start of the sweep (``alpha = 0``) blocks only
    while the velocity points into it beyond the round-off of pymunk's solver.
    """
    if hit is None:
        return False
    alpha, nx, ny = hit
    return alpha > 0.0 or nx * vx + ny * vy < -_APPROACH_TOL * math.hypot(vx, vy)


def _reflect(v: tuple[float, float], normal: tuple[float, float]) -> tuple[float, float]:
    """Velocity ``v`` mirrored about the unit ``normal`` if it points against it."""
    along = v[0] * normal[0] + v[1] * normal[1]
    if along >= 0.0:
        return v
    return v[0] - 2.0 * along * normal[0], v[1] - 2.0 * along * normal[1]
