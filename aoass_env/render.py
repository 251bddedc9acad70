"""Pygame drawing of the AOASS environment (HighwayEnv-style: the env owns one :class:`Renderer`).

A frame shows, bottom to top: the field and its border, the ideal spiral with its waypoints
(blocked ones as red crosses), the static obstacles, the anchor's trail and the beacons broadcast
so far, the anchor's own coverage map (free cells it does not yet know to be covered, shaded by
their deficit), the range-sensor rays (faint), the sensor nodes coloured by coverage, the
follower's current target, the moving obstacles, the anchor with a heading line, and a status line.

Speed: everything fixed for an episode (field, spiral, obstacles) is drawn once per episode onto
a history layer; the trail and the beacons are then added to that layer incrementally, so a
frame is one blit plus the nodes and the few moving parts. A new episode is recognised by the
identity of the :class:`~aoass_env.simulator.Simulator`.

``"rgb_array"`` draws on an off-screen ``pygame.Surface`` and never initialises pygame's display,
so it needs no window system (and no ``SDL_VIDEODRIVER=dummy``); ``"human"`` opens a window.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pygame

from aoass_env.planning import WaypointFollower
from aoass_env.simulator import Simulator

__all__ = ["COLORS", "Renderer"]

Color = tuple[int, int, int]

#: RGB colours of the drawn elements.
COLORS: dict[str, Color] = {
    "margin": (40, 44, 52),
    "field": (250, 250, 246),
    "border": (20, 20, 20),
    "spiral": (214, 222, 236),
    "waypoint": (150, 170, 205),
    "blocked": (215, 50, 50),
    "obstacle": (120, 124, 132),
    "obstacle_edge": (70, 72, 78),
    "trail": (60, 120, 215),
    "beacon": (20, 45, 130),
    "ray": (222, 228, 240),
    "node_silent": (165, 165, 165),   # heard no beacon
    "node_heard": (240, 150, 30),     # heard beacons, not covered yet
    "node_covered": (35, 165, 70),    # covered (Eq. 18)
    "uncovered": (200, 60, 160),      # coverage map: free cells not known to be covered
    "target": (200, 40, 200),
    "moving": (190, 60, 60),
    "moving_edge": (110, 25, 25),
    "anchor": (25, 25, 25),
    "heading": (255, 210, 0),
    "text": (235, 235, 235),
}

_NODE_RADIUS_PX = 3
_BEACON_RADIUS_PX = 1
_TRAIL_WIDTH_PX = 2
_MIN_BODY_RADIUS_PX = 3
_MIN_ANCHOR_RADIUS_PX = 5
#: Opacity (0-255) of a coverage-map cell with deficit 1 (it heard nothing).
_COVERAGE_ALPHA = 110
#: Open human-mode renderers: pygame has one display per process, which they share; it is
#: quit when the last of them closes (quitting it at the first close broke the others).
_HUMAN_OPEN = 0


class Renderer:
    """Draws a :class:`~aoass_env.simulator.Simulator` and its follower with pygame.

    Args:
        render_mode: ``"rgb_array"`` (frames as arrays) or ``"human"`` (a pygame window).
        fps: frame rate of the human window (frames per second).
        size: side of the square frame (px).
        show_rays: draw the anchor's range-sensor rays faintly.
        show_coverage: shade the free cells the anchor's coverage map does not yet count as
            covered (:mod:`aoass_env.planning.coverage`), darker the larger their deficit.
    """

    def __init__(self, render_mode: str, fps: int, size: int = 640, *,
                 show_rays: bool = True, show_coverage: bool = True) -> None:
        if render_mode not in ("rgb_array", "human"):
            raise ValueError(f"render_mode={render_mode!r} must be 'rgb_array' or 'human'")
        if size < 64:
            raise ValueError(f"size={size} px must be at least 64")
        self.render_mode = render_mode
        self.fps = fps
        self.size = size
        self.show_rays = show_rays
        self.show_coverage = show_coverage
        pygame.font.init()
        self._font = pygame.font.Font(None, max(14, size // 32))
        self._header = self._font.get_linesize() + 4   # status-line strip above the field (px)
        self._canvas: pygame.Surface | None
        if render_mode == "human":
            global _HUMAN_OPEN
            pygame.display.init()
            pygame.display.set_caption("AOASS-v0")
            self._canvas = pygame.display.set_mode((size, size))
            _HUMAN_OPEN += 1
            self._clock = pygame.time.Clock()
        else:
            self._canvas = pygame.Surface((size, size))
        self._sim: Simulator | None = None
        self._history = pygame.Surface((size, size))
        self._scale = 1.0               # px per metre
        self._origin = (0.0, 0.0)       # screen position (px) of world (0, 0), bottom left
        self._n_path = 0                # path points already on the history layer
        self._n_beacons = 0             # beacons already on the history layer

    # --- copies -------------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        """The settings alone: pygame's fonts and surfaces do not pickle. A copy draws its
        first frame afresh (static layer, then the whole trail so far), the same frame."""
        return {"render_mode": self.render_mode, "fps": self.fps, "size": self.size,
                "show_rays": self.show_rays, "show_coverage": self.show_coverage}

    def __setstate__(self, state: dict[str, Any]) -> None:
        settings = dict(state)
        self.__init__(settings.pop("render_mode"), settings.pop("fps"), **settings)

    # --- coordinates --------------------------------------------------------------------------
    def to_screen(self, points: np.ndarray) -> np.ndarray:
        """Screen pixels (K, 2) float (x right, y down) of world points (K, 2) [m] (y up)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        return np.column_stack([self._origin[0] + p[:, 0] * self._scale,
                                self._origin[1] - p[:, 1] * self._scale])

    def _px(self, metres: float, minimum: int = 1) -> int:
        return max(minimum, round(metres * self._scale))

    # --- per episode --------------------------------------------------------------------------
    def _new_episode(self, sim: Simulator) -> None:
        """Fit the field into the frame and draw the static layer: field, spiral, obstacles."""
        self._sim = sim
        self._n_path = self._n_beacons = 0
        w, h = sim.map.width, sim.map.height
        pad = 6
        avail_w, avail_h = self.size - 2 * pad, self.size - self._header - pad
        self._scale = min(avail_w / w, avail_h / h)
        left = pad + 0.5 * (avail_w - w * self._scale)
        top = self._header + 0.5 * (avail_h - h * self._scale)
        self._origin = (left, top + h * self._scale)

        s = self._history
        s.fill(COLORS["margin"])
        field = pygame.Rect(round(left), round(top), round(w * self._scale),
                            round(h * self._scale))
        pygame.draw.rect(s, COLORS["field"], field)
        spiral = sim.spiral
        wps = self.to_screen(spiral.waypoints)
        if len(wps) > 1:
            pygame.draw.lines(s, COLORS["spiral"], False, wps.tolist(), 1)
        for x, y in wps[~spiral.blocked].tolist():
            pygame.draw.circle(s, COLORS["waypoint"], (x, y), 2)
        for poly in sim.map.polygons:
            pts = self.to_screen(poly).tolist()
            pygame.draw.polygon(s, COLORS["obstacle"], pts)
            pygame.draw.polygon(s, COLORS["obstacle_edge"], pts, 1)
        for x, y in wps[spiral.blocked].tolist():
            pygame.draw.line(s, COLORS["blocked"], (x - 3, y - 3), (x + 3, y + 3), 2)
            pygame.draw.line(s, COLORS["blocked"], (x - 3, y + 3), (x + 3, y - 3), 2)
        pygame.draw.rect(s, COLORS["border"], field.inflate(2, 2), 2)

    def _extend_history(self, sim: Simulator) -> None:
        """Add the trail segments and beacons recorded since the last frame."""
        path = sim.recorder.path_points
        if len(path) > max(self._n_path, 1):
            new = self.to_screen(path[max(self._n_path - 1, 0):]).tolist()
            pygame.draw.lines(self._history, COLORS["trail"], False, new, _TRAIL_WIDTH_PX)
            self._n_path = len(path)
        if sim.recorder.n_beacons > self._n_beacons:
            beacons = sim.recorder.beacon_positions
            for x, y in self.to_screen(beacons[self._n_beacons:]).tolist():
                pygame.draw.circle(self._history, COLORS["beacon"], (x, y), _BEACON_RADIUS_PX)
            self._n_beacons = len(beacons)

    # --- per frame ----------------------------------------------------------------------------
    def draw(self, sim: Simulator, follower: WaypointFollower) -> np.ndarray | None:
        """Draw the current state; an (H, W, 3) uint8 frame in ``"rgb_array"`` mode, else None
        (the window is updated and the clock ticked at ``fps``)."""
        if self._canvas is None:
            raise RuntimeError("the renderer is closed")
        if sim is not self._sim:
            self._new_episode(sim)
        self._extend_history(sim)
        c, world, net = self._canvas, sim.world, sim.network
        c.blit(self._history, (0, 0))
        anchor = self.to_screen(world.position)[0]

        if self.show_coverage:
            self._draw_coverage(sim)
        if self.show_rays:
            angles, dists = world.ray_angles(), world.ray_distances()
            ends = world.position + dists[:, None] * np.column_stack([np.cos(angles),
                                                                      np.sin(angles)])
            for end in self.to_screen(ends).tolist():
                pygame.draw.line(c, COLORS["ray"], anchor.tolist(), end)

        heard, covered = net.heard > 0, net.covered
        nodes = self.to_screen(sim.nodes)
        for key, mask in (("node_silent", ~heard), ("node_heard", heard & ~covered),
                          ("node_covered", covered)):
            for x, y in nodes[mask].tolist():
                pygame.draw.circle(c, COLORS[key], (x, y), _NODE_RADIUS_PX)

        target = follower.target
        if target is not None:
            pygame.draw.circle(c, COLORS["target"], self.to_screen(target)[0].tolist(), 6, 2)

        r_moving = self._px(sim.config.moving_obstacle_radius, _MIN_BODY_RADIUS_PX)
        for x, y in self.to_screen(world.moving_positions).tolist():
            pygame.draw.circle(c, COLORS["moving"], (x, y), r_moving)
            pygame.draw.circle(c, COLORS["moving_edge"], (x, y), r_moving, 1)

        r_anchor = self._px(sim.config.anchor_radius, _MIN_ANCHOR_RADIUS_PX)
        nose = anchor + (r_anchor + 6) * np.array([math.cos(world.heading),
                                                   -math.sin(world.heading)])
        pygame.draw.line(c, COLORS["anchor"], anchor.tolist(), nose.tolist(), 4)
        pygame.draw.circle(c, COLORS["anchor"], anchor.tolist(), r_anchor)
        pygame.draw.line(c, COLORS["heading"], anchor.tolist(), nose.tolist(), 2)

        status = (f"t {world.time:7.1f} s   coverage {100 * net.coverage_ratio:5.1f} %   "
                  f"map {100 * sim.coverage_map.ratio:5.1f} %   beacons {net.beacons_sent}   "
                  f"collisions {sim.collisions}")
        c.blit(self._font.render(status, True, COLORS["text"]), (6, 3))

        if self.render_mode == "human":
            pygame.event.pump()
            pygame.display.flip()
            self._clock.tick(self.fps)
            return None
        # same pixels as surfarray.array3d transposed to (H, W, 3), in a third of the time
        rgb = bytearray(pygame.image.tobytes(c, "RGB"))
        return np.frombuffer(rgb, dtype=np.uint8).reshape(self.size, self.size, 3)

    def _draw_coverage(self, sim: Simulator) -> None:
        """Shade the coverage map's uncovered free cells (alpha by deficit) over the field."""
        deficit = np.nan_to_num(sim.coverage_map.raster(), nan=0.0)      # (nx, ny)
        rgba = np.zeros((*deficit.shape[::-1], 4), dtype=np.uint8)        # rows = y, top first
        rgba[..., :3] = COLORS["uncovered"]
        rgba[..., 3] = np.round(_COVERAGE_ALPHA * deficit.T[::-1]).astype(np.uint8)
        ny, nx = rgba.shape[:2]
        layer = pygame.image.frombuffer(rgba.tobytes(), (nx, ny), "RGBA")
        cell = sim.coverage_map.cell * self._scale
        size = (round(nx * cell), round(ny * cell))
        top = self._origin[1] - ny * cell
        # the last cells of a field that is not a whole number of cells reach past it: clip
        # to the field, or the shading spills over the margin and the status line
        field = pygame.Rect(round(self._origin[0]), round(self._origin[1] - sim.map.height
                                                          * self._scale),
                            round(sim.map.width * self._scale),
                            round(sim.map.height * self._scale))
        clip = self._canvas.get_clip()
        self._canvas.set_clip(field.clip(clip))
        self._canvas.blit(pygame.transform.scale(layer, size), (round(self._origin[0]),
                                                                round(top)))
        self._canvas.set_clip(clip)

    def close(self) -> None:
        """Close the window (human mode) and drop the surfaces; idempotent."""
        if self.render_mode == "human" and self._canvas is not None:
            global _HUMAN_OPEN
            _HUMAN_OPEN -= 1
            if _HUMAN_OPEN == 0:
                pygame.display.quit()
        self._canvas = None
        self._sim = None
