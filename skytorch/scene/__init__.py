"""Scenes: describe a sky, plan what matters, render it, tone-map it.

* :class:`Scene` — observer, time, view, spectral grid, atmosphere, lights, tolerance;
* :func:`plan` — the effects that can change the image beyond the tolerance
  (:data:`EFFECTS`, :data:`FIDELITY`);
* :func:`render` — per-component spectral radiance, XYZ, sRGB, V mag arcsec^-2;
  :func:`render_times` — the same over several instants (dimension ``time``);
  :func:`render_observers` — a scene with several observers (dimension ``observer``);
* :class:`SceneResources` — the tables a scene's planner and renderers share (atmosphere,
  shadow, transmittance, star and skyglow tables), built from a :class:`SceneSpec`; keep
  one to render a time series (``Scene.render(resources=...)``);
* :func:`tonemap`, :func:`scene_png` — exposure, night vision, PNG.

Examples
--------
>>> import skytorch as st
>>> ds = st.Scene(time="2015-06-21T12:00", lat_deg=48.85, lon_deg=2.35, size=16,
...               fidelity="fast").render()
>>> ds.attrs["effects_computed"]
'sky,sun'
"""

from skytorch.scene.planner import Plan, plan
from skytorch.scene.presets import EFFECTS, FIDELITY
from skytorch.scene.render import COMPONENTS, Knobs, render, render_observers, render_times
from skytorch.scene.resources import SceneResources, SceneSpec
from skytorch.scene.scene import OUTPUTS, VIEWS, Scene, View
from skytorch.scene.tonemap import scene_png, tonemap

__all__ = ["COMPONENTS", "EFFECTS", "FIDELITY", "OUTPUTS", "VIEWS", "Knobs", "Plan", "Scene",
           "SceneResources", "SceneSpec", "View", "plan", "render", "render_observers",
           "render_times", "scene_png", "tonemap"]
