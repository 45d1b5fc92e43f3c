"""Blueprint views that fit the data (issue 32): what every pipeline's recording shares.

* Planar runs are drawn from straight above, not in a tilted perspective: :func:`top_down_view`
  is a 3D view whose eye looks down the z axis at the scene's centre from the height that shows
  its whole extent, with a 1 m line grid on the ground plane and the world's x (red) and y
  (green) axes drawn 1 m long at the origin (:func:`log_metre_axes`), so a distance can be read
  off the grid. (Rerun's 2D view draws y downwards, image-style -- rerun-io/rerun#1387 -- so a
  map in it would be mirrored; everything planar lies on z = 0, and a plane seen square-on
  through a perspective camera keeps a uniform scale.)
* Time-series views keep their legend off the curves: :func:`series_view` puts the legend in the
  top-right corner and gives the y axis headroom above the data (``LEGEND_HEADROOM``), so the
  corner the legend occupies is empty.
* Point labels are shown only when they cannot overlap (:func:`labels_fit`); otherwise the ids
  stay on the points and appear on hover.
"""

from __future__ import annotations

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

#: the 3D view's vertical field of view (re_renderer's default eye), for the top-down height
VIEW_FOV_Y_RAD = float(np.deg2rad(55.0))
#: the scene takes this share of the view's height, the rest is margin
FILL = 0.85
#: the y axis ends this many times above the highest value: the legend's corner stays empty
LEGEND_HEADROOM = 1.45
#: label characters are about this wide on screen relative to the view (rough, conservative)
LABEL_WIDTH_SHARE = 0.03


def top_down_view(origin: str, name: str, world_min_xy, world_max_xy, grid_spacing_m: float = 1.0,
                  **kwargs) -> rrb.Spatial3DView:
    """A view of the planar scene between ``world_min_xy`` and ``world_max_xy`` (metres) seen
    from straight above, with a ``grid_spacing_m`` grid on z = 0."""
    lo = np.asarray(world_min_xy, float).reshape(2)
    hi = np.asarray(world_max_xy, float).reshape(2)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        lo, hi = np.zeros(2), np.ones(2)
    centre = 0.5 * (lo + hi)
    extent_m = max(float(np.max(hi - lo)), 1.0)
    height_m = 0.5 * extent_m / FILL / np.tan(0.5 * VIEW_FOV_Y_RAD)
    eye = rrb.archetypes.EyeControls3D(
        kind=rrb.components.Eye3DKind.Orbital, position=[centre[0], centre[1], height_m],
        look_target=[centre[0], centre[1], 0.0], eye_up=[0.0, 1.0, 0.0])
    grid = rrb.archetypes.LineGrid3D(visible=True, spacing=grid_spacing_m, plane=rr.components.Plane3D.XY)
    return rrb.Spatial3DView(origin=origin, name=name, eye_controls=eye, line_grid=grid, **kwargs)


def scene_bounds(*points_xy) -> tuple[np.ndarray, np.ndarray]:
    """(min_xy, max_xy) over every finite point of the given (N, >=2) arrays."""
    stacked = [np.asarray(p, float).reshape(-1, np.asarray(p).shape[-1])[:, :2] for p in points_xy
               if p is not None and np.asarray(p).size]
    if not stacked:
        return np.zeros(2), np.ones(2)
    xy = np.concatenate(stacked)
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    if len(xy) == 0:
        return np.zeros(2), np.ones(2)
    return xy.min(axis=0), xy.max(axis=0)


def log_metre_axes(stream, entity: str, length_m: float = 1.0) -> None:
    """The world's x (red) and y (green) axes, ``length_m`` long at the origin (static)."""
    stream.log(entity, rr.Arrows3D(origins=np.zeros((2, 3)), vectors=[[length_m, 0, 0], [0, length_m, 0]],
                                   colors=[(220, 40, 40), (40, 170, 40)], labels=[f"x {length_m:g} m", f"y {length_m:g} m"],
                                   radii=[0.02]), static=True)


def series_view(origin: str, name: str, y_max: float | None = None, y_min: float = 0.0,
                **kwargs) -> rrb.TimeSeriesView:
    """A time-series view whose legend (top right) sits above the data: with ``y_max`` (the
    highest value plotted) the y axis runs to ``LEGEND_HEADROOM`` times it."""
    axis = None
    if y_max is not None and np.isfinite(y_max) and y_max > y_min:
        axis = rrb.archetypes.ScalarAxis(range=(float(y_min), float(y_min + LEGEND_HEADROOM * (y_max - y_min))))
    legend = rrb.archetypes.PlotLegend(corner=rrb.components.Corner2D.RightTop, visible=True)
    return rrb.TimeSeriesView(origin=origin, name=name, axis_y=axis, plot_legend=legend, **kwargs)


def labels_fit(points_xy, view_extent_m: float | None = None, max_labels: int = 40) -> bool:
    """Whether labels on these points can be drawn without overlapping: at most ``max_labels``
    points, every two of them farther apart than a label's width in a view showing
    ``view_extent_m`` (default: the points' own extent)."""
    xy = np.asarray(points_xy, float).reshape(-1, 2)
    if len(xy) <= 1:
        return True
    if len(xy) > max_labels:
        return False
    extent = view_extent_m if view_extent_m is not None else float(np.max(np.ptp(xy, axis=0)))
    d = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    return bool(d.min() > LABEL_WIDTH_SHARE * max(extent, 1e-9))


def planar_2d_view(prefix: str, name: str, world: str = "world") -> rrb.Spatial2DView:
    """A 2D view of ``<prefix><world>/**`` with the world's y axis pointing up. Rerun's 2D views
    draw y downwards (image convention, rerun-io/rerun#1387), which mirrors a map; the view's
    origin is therefore the prefix and ``<prefix><world>`` carries the y-flip that
    :func:`log_world_y_up` logs."""
    origin = prefix.rstrip("/") or "/"
    return rrb.Spatial2DView(origin=origin, contents=[f"+ $origin/{world}/**"], name=name)


def log_world_y_up(stream, world_entity: str) -> None:
    """The y-flip that makes a :func:`planar_2d_view` show the world with y up (static)."""
    stream.log(world_entity, rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
