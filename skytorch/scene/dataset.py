"""The Dataset of a rendered scene, and the stacking of several renders along a dimension.

:func:`scene_dataset` turns the renderer's component images into an ``xarray.Dataset``
(:func:`skytorch.dataset.build_dataset`: per-component and total spectral radiance, XYZ,
tone-mapped sRGB, V surface brightness, the scene's parameters and the planner's
decisions as attributes); :func:`stack_frames` stacks renders along ``time`` or
``observer`` (:func:`skytorch.scene.render.render_times`,
:func:`skytorch.scene.render.render_observers`).
"""

from __future__ import annotations

import math

import numpy as np
import torch
import xarray as xr

from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable
from skytorch.scene.presets import EFFECTS
from skytorch.scene.tonemap import tonemap

__all__ = ["REFERENCES", "scene_dataset", "stack_frames"]


def scene_dataset(scene, view, plan, components, total, seconds):
    """Dataset of a rendered scene: per-component and total radiance, XYZ, sRGB, V mag.

    Parameters
    ----------
    scene : Scene
        One observer (its outputs, wavelengths and parameters).
    view : View
        The image's pixels.
    plan : Plan
        The planner's decisions (attributes ``effects_computed``, ``effects_skipped``).
    components : dict
        Spectral radiance of each component (*view, wl) [W m^-2 sr^-1 nm^-1].
    total : Tensor (*view, wl)
        Their sum.
    seconds : dict
        Wall time of each component and ``total`` [s] (attributes).

    Returns
    -------
    xarray.Dataset
    """
    from skytorch.moon.sky import radiance_to_mag_arcsec2
    from skytorch.scene.visibility_map import sky_mag_from_radiance
    from skytorch.spectrum import spectrum_to_xyz
    from skytorch.stars.visibility import limiting_magnitude

    wavelength = scene.wavelength_nm()
    dims = view.dims
    coords = {name: coordinate(name, values, _COORD_SPECS[name])
              for name, values in view.coords.items()}
    coords["wavelength"] = coordinate("wavelength", wavelength, VariableSpec(
        "nm", "wavelength", "Vacuum wavelength.", "radiation_wavelength"))
    coords["component"] = coordinate("component", np.array(list(components)), VariableSpec(
        "1", "image component", "Light source of the component (see docs/scene.md)."))
    data = {
        "altitude": variable(dims, 90.0 - torch.rad2deg(view.zenith_rad), VariableSpec(
            "degree", "altitude of the view direction", "Above the horizon.")),
        "azimuth_of_view": variable(dims, torch.rad2deg(view.azimuth_rad), VariableSpec(
            "degree", "azimuth of the view direction", "From north through east.")),
        "solid_angle": variable(dims, view.solid_angle_sr, VariableSpec(
            "sr", "pixel solid angle", "Solid angle of each pixel (0 off the sky).")),
    }
    outputs = scene.outputs
    if "spectral" in outputs:
        data["radiance"] = variable((*dims, "wavelength"), total, VariableSpec(
            "W m-2 sr-1 nm-1", "sky spectral radiance", "Sum of the components."))
        data["component_radiance"] = variable(
            ("component", *dims, "wavelength"), torch.stack(list(components.values())),
            VariableSpec("W m-2 sr-1 nm-1", "spectral radiance of each component",
                         "Radiance of each light source; the sum is radiance."))
    xyz = spectrum_to_xyz(total, wavelength, luminous=True)
    if "xyz" in outputs:
        coords["tristimulus"] = coordinate("tristimulus", np.array(["X", "Y", "Z"]), VariableSpec(
            "1", "CIE 1931 tristimulus", "X, Y, Z"))
        data["xyz"] = variable((*dims, "tristimulus"), xyz, VariableSpec(
            "cd m-2", "CIE 1931 XYZ", "Tristimulus values with K_m = 683 lm/W (Y is "
            "luminance)."))
        data["luminance"] = variable(dims, xyz[..., 1], VariableSpec(
            "cd m-2", "luminance", "Photopic luminance of the sky.",
            "surface_photopic_radiance"))
    if "srgb" in outputs:
        coords["channel"] = coordinate("channel", np.array(["R", "G", "B"]), VariableSpec(
            "1", "sRGB channel", "R, G, B"))
        rgb, exposure = tonemap(xyz, view.valid)
        data["srgb"] = variable((*dims, "channel"), rgb, VariableSpec(
            "1", "tone-mapped sRGB", "Display sRGB in [0, 1] (exposure and Reinhard "
            "operator, skytorch.scene.tonemap)."))
    if "v_mag" in outputs:
        mags = radiance_to_mag_arcsec2(total.to(torch.float64).clamp(min=1e-300),
                                       wavelength.to(torch.float64))
        mags = torch.where(view.valid, mags, torch.full_like(mags, float("nan")))
        data["v_mag_arcsec2"] = variable(dims, mags, VariableSpec(
            "mag arcsec-2", "V surface brightness", "Johnson V surface brightness of the "
            "sky (NaN off the sky)."))
        # the background a star is seen against: every component but the stars drawn (a
        # pixel's own star does not hide it); darker than 40 mag arcsec^-2 the limit is
        # that of a black background (sky_mag_from_radiance)
        background = sum(value for name, value in components.items() if name != "stars")
        background_mags = sky_mag_from_radiance(background.to(torch.float64),
                                                wavelength.to(torch.float64))
        limit = torch.full_like(mags, float("nan"))
        limit[view.valid] = limiting_magnitude(background_mags[view.valid])
        data["limiting_magnitude"] = variable(dims, limit, VariableSpec(
            "mag", "naked-eye limiting magnitude", "Faintest V magnitude of a star seen "
            "against the sky of each pixel, the stars drawn left out of the sky (Schaefer "
            "1990 with his default observer, 7 mm pupil, F_s = 1; to compare with a star's "
            "magnitude after extinction; NaN off the sky)."))
        stack = torch.stack(list(components.values())).to(torch.float64)
        lit = (stack > 0).any(-1) & view.valid
        component_mags = radiance_to_mag_arcsec2(stack.clamp(min=1e-300),
                                                 wavelength.to(torch.float64))
        component_mags = torch.where(lit, component_mags,
                                     torch.full_like(component_mags, float("nan")))
        data["component_v_mag_arcsec2"] = variable(
            ("component", *dims), component_mags, VariableSpec(
                "mag arcsec-2", "V surface brightness of each component",
                "Johnson V surface brightness of each light source alone (NaN where it "
                "adds no light or off the sky)."))
    g = plan.geometry
    parameters = scene.parameters()
    parameters.update({f"seconds_{k}": round(v, 4) for k, v in seconds.items()})
    parameters["seconds_plan"] = round(plan.seconds, 4)
    parameters.update({
        "sun_altitude_deg": g.sun_altitude_deg, "sun_azimuth_deg": g.sun_azimuth_deg,
        "moon_altitude_deg": g.moon_altitude_deg, "moon_azimuth_deg": g.moon_azimuth_deg,
        "moon_phase_angle_deg": math.degrees(g.phase_angle_rad),
        "moon_shadow_offset_km": g.shadow_offset_m / 1e3,
        "penumbra_radius_km": g.penumbra_radius_m / 1e3,
    })
    if "srgb" in outputs:
        parameters["exposure"] = exposure
    ds = build_dataset(data, coords, title=f"Sky scene at {str(scene.time)[:19]} UTC",
                       references=list(REFERENCES), parameters=parameters)
    ds.attrs.update(plan.attrs())
    return ds


REFERENCES = (
    "Müller, Engel & Döllner 2012, Single-Pass Rendering of Day and Night Sky Phenomena, "
    "VMV 2012, doi:10.2312/PE/VMV/VMV12/055-062",
    "Falchi et al. 2016, The new world atlas of artificial night sky brightness, "
    "Sci. Adv. 2, e1600377, doi:10.1126/sciadv.1600377",
    "Reinhard et al. 2002, Photographic tone reproduction for digital images, "
    "ACM TOG 21, 267, doi:10.1145/566654.566575",
)


_COORD_SPECS = {
    "x": VariableSpec("1", "fisheye x", "Image x in units of the horizon radius (west +)."),
    "y": VariableSpec("1", "fisheye y", "Image y in units of the horizon radius (north +)."),
    "elevation": VariableSpec("degree", "elevation", "Elevation of the pixel centre."),
    "azimuth": VariableSpec("degree", "azimuth", "Azimuth of the pixel centre from north "
                                                "through east."),
    "direction": VariableSpec("1", "direction index", "Index of the view direction."),
    "camera_x": VariableSpec("degree", "camera x angle", "Angle from the image centre along "
                                                        "the image's horizontal axis (right +)."),
    "camera_y": VariableSpec("degree", "camera y angle", "Angle from the image centre along "
                                                        "the image's vertical axis (zenith +)."),
}




#: planner decisions kept per frame when they differ between stacked frames
_PER_FRAME_DECISIONS = ("sky_scattering_orders", "moon_scattering_orders",
                        "scattering_orders_reason")


def stack_frames(frames, dim: str, coordinate, title: str):
    """Stack rendered scenes along ``dim``.

    The changing variables get the dimension, the planner's decisions become string variables over
    it (so do the orders of scattering, when they differ between frames), the other attributes
    that differ between frames are dropped and ``effects_computed`` lists the union.
    """
    computed = [f.attrs["effects_computed"] for f in frames]
    skipped = [f.attrs["effects_skipped"] for f in frames]
    varying = [k for k in frames[0].attrs if any(f.attrs.get(k) != frames[0].attrs[k]
                                                  for f in frames[1:])]
    static = ("altitude", "azimuth_of_view", "solid_angle")
    changing = [name for name in frames[0].data_vars
                if name not in static or any(not f[name].equals(frames[0][name])
                                             for f in frames[1:])]
    fill = {name: (np.nan if "mag" in name else 0.0) for name in changing}
    stacked = xr.concat([_no_attrs(f) for f in frames], dim=dim, data_vars=changing,
                        coords="minimal", compat="override", join="outer", fill_value=fill)
    stacked = stacked.assign_coords({dim: coordinate})
    # fixed-width unicode (numpy "<U"), the dtype netCDF gives back: an exact round trip
    stacked["effects_computed"] = variable((dim,), np.array(computed, dtype=np.str_),
                                           VariableSpec("1", "effects computed",
                                                        f"Planner decision per {dim}."))
    stacked["effects_skipped"] = variable((dim,), np.array(skipped, dtype=np.str_),
                                          VariableSpec("1", "effects skipped",
                                                       "Skipped effects and reasons."))
    for key in _PER_FRAME_DECISIONS:
        if key in varying and all(key in f.attrs for f in frames):
            values = np.array([str(f.attrs[key]) for f in frames], dtype=np.str_)
            stacked[key] = variable((dim,), values, VariableSpec(
                "1", key.replace("_", " "), f"Planner decision per {dim}."))
    stacked.attrs = {k: v for k, v in frames[0].attrs.items() if k not in varying}
    union = {e for c in computed for e in c.split(",") if e}
    stacked.attrs["effects_computed"] = ",".join(e for e in EFFECTS if e in union)
    stacked.attrs["title"] = title
    return stacked


def _no_attrs(dataset):
    out = dataset.copy()
    out.attrs = {}
    return out
