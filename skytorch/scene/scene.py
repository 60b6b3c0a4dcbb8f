"""Scene description: observer, time, view, spectral grid, atmosphere, lights, tolerance.

A :class:`Scene` holds what a user asks for; :meth:`Scene.plan` decides which effects
can change the image beyond the tolerance (:mod:`skytorch.scene.planner`) and
:meth:`Scene.render` composes the components (:mod:`skytorch.scene.render`) into an
``xarray.Dataset``.

Views
-----
``"fisheye"``
    All-sky azimuthal-equidistant image of ``size × size`` pixels, north up and east to
    the left (as seen looking up); the zenith distance grows linearly with the radius
    to 90° at the rim. Dimensions ``(y, x)``.
``"panorama"``
    Equirectangular ``size × 2 size`` grid of elevation (0–90°) by azimuth (0–360°,
    from north through east). Dimensions ``(elevation, azimuth)``.
``"camera"``
    A gnomonic (pinhole-camera) image of ``size × size`` pixels and ``fov_deg`` across,
    centred on a given altitude and azimuth or on the Sun or Moon (their apparent,
    refracted places), zenith up: a telescope's view that resolves the lunar disc.
    Dimensions ``(camera_y, camera_x)``, coordinates the angles from the centre along
    the image axes [degree].
directions
    A mapping or pair of arrays of altitude and azimuth [degree]: dimension
    ``direction``. Point sources (Sun disc, Moon disc, stars) occupy no direction of
    such a view and are not drawn.

Examples
--------
>>> import skytorch as st
>>> scene = st.Scene(time="2015-09-28T02:47", lat_deg=52.52, lon_deg=13.40, size=32)
>>> plan = scene.plan()
>>> "eclipse" in plan.computed
True
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np
import torch

from skytorch._angles import wrap_to_turn
from skytorch._toml import loads as toml_loads
from skytorch._validate import as_tensor, check_choice, check_finite, check_int, check_range
from skytorch.constants import NATURAL_MAG_RANGE, NATURAL_ZENITH_SKY_MAG_ARCSEC2
from skytorch.dataset import open_dataset
from skytorch.scene.planner import plan as make_plan
from skytorch.scene.planner import requested_orders
from skytorch.scene.presets import EFFECTS, FIDELITY_PRESETS, SCATTERING_ORDER_CHOICES
from skytorch.scene.render import render as render_scene
from skytorch.scene.resources import SceneResources, SceneSpec

#: view kinds of a scene
VIEWS = ("fisheye", "panorama", "directions", "camera")
#: what a camera view may be centred on
CAMERA_TARGETS = ("moon", "sun")
#: outputs a scene can produce
OUTPUTS = ("spectral", "xyz", "srgb", "v_mag")
#: gradients of the natural background (see :func:`skytorch.scene.render.natural_gradient`)
NATURAL_MODELS = ("garstang1989", "vanrhijn1921", "constant", "leinert1998")
#: 10.7 cm solar flux range of the airglow law [sfu] (:func:`skytorch.nightsky.airglow_zenith_mag`)
SOLAR_FLUX_RANGE_SFU = (50.0, 400.0)
#: keys of the ``directions`` mapping of a directions view
DIRECTION_KEYS = ("altitude_deg", "azimuth_deg")
#: keys of the ``camera`` mapping of a camera view
CAMERA_KEYS = ("fov_deg", "target", "altitude_deg", "azimuth_deg")
#: field of a camera view [degree]: (0, 120]
CAMERA_FOV_RANGE_DEG = (0.0, 120.0)
#: largest image side [pixels] (a 8192² fisheye already holds 1.6 GB per component)
MAX_SIZE = 8192
#: share of the zenith background emitted by the airglow layer (Garstang 1989; Patat 2003)
DEFAULT_AIRGLOW_FRACTION = 0.6
#: stratospheric optical depth at 550 nm accepted by a scene: from none to beyond the
#: largest eruption of the record (Pinatubo, about 0.15 in 1992)
STRATOSPHERIC_AOD_RANGE = (0.0, 1.0)
#: faintest-star limit [V mag]: the range of :func:`skytorch.stars.bright_stars`
STAR_LIMIT_RANGE_MAG = (-30.0, 15.0)
#: height of the airglow layer [m]
AIRGLOW_HEIGHT_RANGE_M = (10_000.0, 1_000_000.0)


@dataclass
class View:
    """Directions of the pixels of a scene and their solid angles.

    Attributes
    ----------
    dims : tuple of str
        Dataset dimensions of the image.
    coords : dict
        Coordinate arrays of those dimensions.
    zenith_rad, azimuth_rad : Tensor (*dims)
        Direction of each pixel centre [rad] (azimuth from north through east).
    solid_angle_sr : Tensor (*dims)
        Solid angle of each pixel [sr] (zero outside a fisheye's circle or for a
        directions view).
    valid : Tensor (*dims) bool
        Pixels that show the sky.
    pixel_rad : float
        Angular size of a pixel at its centre [rad] (0 for directions).
    """

    kind: str
    dims: tuple[str, ...]
    coords: dict
    zenith_rad: torch.Tensor
    azimuth_rad: torch.Tensor
    solid_angle_sr: torch.Tensor
    valid: torch.Tensor
    pixel_rad: float

    @property
    def shape(self) -> tuple[int, ...]:
        """Image shape (the sizes of ``dims``)."""
        return tuple(self.zenith_rad.shape)

    def unit_vectors(self) -> torch.Tensor:
        """Return unit vectors (*dims, 3) of the pixel directions in (north, east, up), float64."""
        if getattr(self, "_unit", None) is None:
            zenith = self.zenith_rad.to(torch.float64)
            azimuth = self.azimuth_rad.to(torch.float64)
            self._unit = torch.stack([torch.sin(zenith) * torch.cos(azimuth),
                                      torch.sin(zenith) * torch.sin(azimuth),
                                      torch.cos(zenith)], dim=-1)
        return self._unit

    def pixel_index(self, altitude_rad: torch.Tensor, azimuth_rad: torch.Tensor) -> torch.Tensor:
        """Flat index of the pixel holding each point (-1 outside the image).

        Parameters
        ----------
        altitude_rad, azimuth_rad : Tensor (n,)
            Directions of point sources [rad].

        Returns
        -------
        Tensor (n,) int64
        """
        altitude = torch.as_tensor(altitude_rad, dtype=torch.float64)
        azimuth = torch.as_tensor(azimuth_rad, dtype=torch.float64)
        outside = torch.full(altitude.shape, -1, dtype=torch.int64)
        if self.kind == "directions":
            return outside
        zenith = 0.5 * math.pi - altitude
        if self.kind == "fisheye":
            n = self.shape[0]
            radius = zenith / (0.5 * math.pi)
            x = -radius * torch.sin(azimuth)
            y = radius * torch.cos(azimuth)
            column = torch.floor((x + 1.0) * 0.5 * n).long()
            row = torch.floor((1.0 - y) * 0.5 * n).long()
            index = row * n + column
            inside = (altitude >= 0.0) & (column >= 0) & (column < n) & (row >= 0) & (row < n)
        elif self.kind == "camera":
            return self._camera_index(altitude, azimuth)
        else:
            n_el, n_az = self.shape
            row = torch.floor(altitude / (0.5 * math.pi) * n_el).long()
            column = torch.floor(wrap_to_turn(azimuth, 2 * math.pi) / (2 * math.pi)
                                 * n_az).long().clamp(max=n_az - 1)
            index = row * n_az + column
            inside = (altitude >= 0.0) & (row < n_el)
        index = torch.where(inside, index, outside)
        if self.kind == "fisheye":
            flat_valid = self.valid.reshape(-1)
            index = torch.where(index >= 0, torch.where(flat_valid[index.clamp(min=0)], index,
                                                        outside), outside)
        return index


    def _camera_index(self, altitude: torch.Tensor, azimuth: torch.Tensor) -> torch.Tensor:
        centre, right, up, half_width = self.frame
        point = torch.stack([torch.cos(altitude) * torch.cos(azimuth),
                             torch.cos(altitude) * torch.sin(azimuth),
                             torch.sin(altitude)], dim=-1)
        depth = point @ centre
        safe = torch.where(depth > 0, depth, torch.ones_like(depth))
        x = (point @ right) / safe / half_width
        y = (point @ up) / safe / half_width
        n = self.shape[0]
        column = torch.floor((x + 1.0) * 0.5 * n).long()
        row = torch.floor((1.0 - y) * 0.5 * n).long()
        inside = (depth > 0) & (column >= 0) & (column < n) & (row >= 0) & (row < n)
        index = torch.where(inside, row * n + column, torch.full_like(column, -1))
        flat_valid = self.valid.reshape(-1)
        return torch.where(index >= 0, torch.where(flat_valid[index.clamp(min=0)], index,
                                                   torch.full_like(index, -1)), index)


def camera_view(altitude_deg: float, azimuth_deg: float, fov_deg: float, size: int,
                dtype=torch.float64) -> View:
    r"""Gnomonic view of ``size × size`` pixels, ``fov_deg`` across, centred on a direction.

    The image plane is tangent to the sphere at the centre, ``x`` to the right (towards
    azimuth + 90°) and ``y`` up (towards the zenith). A pixel of the plane of side
    :math:`\Delta` at :math:`(x, y)` (in units of the focal length) subtends
    :math:`\Delta^2 / (1 + x^2 + y^2)^{3/2}` sr. Pixels below the horizon hold no sky.
    """
    size = check_int("size", size, 2)
    check_range("camera fov_deg", fov_deg, 0.0, 120.0, low_inclusive=False, unit="degree")
    check_range("camera altitude_deg", altitude_deg, -90.0, 90.0, unit="degree")
    h, a = math.radians(float(altitude_deg)), math.radians(float(azimuth_deg))
    centre = torch.tensor([math.cos(h) * math.cos(a), math.cos(h) * math.sin(a), math.sin(h)],
                          dtype=torch.float64)
    right = torch.tensor([-math.sin(a), math.cos(a), 0.0], dtype=torch.float64)
    up = torch.tensor([-math.sin(h) * math.cos(a), -math.sin(h) * math.sin(a), math.cos(h)],
                      dtype=torch.float64)
    half_width = math.tan(0.5 * math.radians(float(fov_deg)))
    centres = ((torch.arange(size, dtype=torch.float64) + 0.5) / size * 2.0 - 1.0) * half_width
    y, x = torch.meshgrid(-centres, centres, indexing="ij")
    direction = centre + x[..., None] * right + y[..., None] * up
    direction = direction / torch.linalg.vector_norm(direction, dim=-1, keepdim=True)
    altitude = torch.asin(direction[..., 2].clamp(-1.0, 1.0))
    azimuth = wrap_to_turn(torch.atan2(direction[..., 1], direction[..., 0]), 2 * math.pi)
    valid = altitude >= 0.0
    pixel = (2.0 * half_width / size) ** 2
    solid_angle = torch.where(valid, pixel / (1.0 + x * x + y * y) ** 1.5,
                              torch.zeros_like(x))
    coords = {"camera_y": np.degrees(np.arctan(-centres.numpy())),
              "camera_x": np.degrees(np.arctan(centres.numpy()))}
    view = View("camera", ("camera_y", "camera_x"), coords,
                (0.5 * math.pi - altitude).to(dtype), azimuth.to(dtype),
                solid_angle.to(dtype), valid, 2.0 * math.atan(half_width) / size)
    view.frame = (centre, right, up, half_width)
    view._unit = direction
    return view


def fisheye_view(size: int, dtype=torch.float64) -> View:
    r"""All-sky azimuthal-equidistant view of ``size × size`` pixels (north up, east left).

    The solid angle of a pixel is :math:`\sin z\,(\pi/2)/r\,\Delta x\,\Delta y` with
    :math:`z = r\pi/2` (the Jacobian of the equidistant projection).
    """
    size = check_int("size", size, 2)
    centres = (torch.arange(size, dtype=dtype) + 0.5) / size * 2.0 - 1.0
    y, x = torch.meshgrid(-centres, centres, indexing="ij")
    radius = torch.sqrt(x * x + y * y)
    zenith = radius * (0.5 * math.pi)
    azimuth = wrap_to_turn(torch.atan2(-x, y), 2 * math.pi)
    valid = radius <= 1.0
    pixel_area = (2.0 / size) ** 2
    jacobian = (0.5 * math.pi) ** 2 * torch.sinc(zenith / math.pi)  # sin z (pi/2) / r
    solid_angle = torch.where(valid, jacobian * pixel_area, torch.zeros_like(zenith))
    coords = {"y": np.asarray(-centres), "x": np.asarray(centres)}
    return View("fisheye", ("y", "x"), coords, zenith.clamp(max=0.5 * math.pi), azimuth,
                solid_angle, valid, math.pi / size)


def panorama_view(size: int, dtype=torch.float64) -> View:
    """Equirectangular view: ``size`` elevations (0–90°) by ``2 size`` azimuths."""
    size = check_int("size", size, 2)
    d_el = 0.5 * math.pi / size
    d_az = 2 * math.pi / (2 * size)
    elevation = (torch.arange(size, dtype=dtype) + 0.5) * d_el
    azimuth = (torch.arange(2 * size, dtype=dtype) + 0.5) * d_az
    el, az = torch.meshgrid(elevation, azimuth, indexing="ij")
    solid_angle = torch.cos(el) * d_el * d_az
    coords = {"elevation": np.degrees(elevation.numpy()), "azimuth": np.degrees(azimuth.numpy())}
    return View("panorama", ("elevation", "azimuth"), coords, 0.5 * math.pi - el, az,
                solid_angle, torch.ones_like(el, dtype=torch.bool), d_el)


def directions_view(altitude_deg, azimuth_deg, dtype=torch.float64) -> View:
    """Return a list of view directions (altitude, azimuth) [degree] (dimension ``direction``)."""
    altitude = torch.as_tensor(np.asarray(altitude_deg, dtype=float), dtype=dtype).reshape(-1)
    azimuth = torch.as_tensor(np.asarray(azimuth_deg, dtype=float), dtype=dtype).reshape(-1)
    if altitude.shape != azimuth.shape:
        raise ValueError("directions: altitude_deg and azimuth_deg must have the same length; "
                         f"got {altitude.numel()} and {azimuth.numel()}")
    check_range("directions altitude_deg", altitude, 0.0, 90.0, unit="degree")
    n = altitude.numel()
    coords = {"direction": np.arange(n)}
    return View("directions", ("direction",), coords, torch.deg2rad(90.0 - altitude),
                torch.deg2rad(azimuth), torch.zeros(n, dtype=dtype),
                torch.ones(n, dtype=torch.bool), 0.0)


def _view_keywords(view: dict, kwargs: dict) -> None:
    """Move the keys of a TOML ``[view]`` table into Scene keywords ``kwargs``.

    ``kind`` becomes ``view``, ``size`` stays, a camera's keys become ``camera`` and the
    altitude and azimuth lists ``directions``; unknown keys stay in ``view``.
    """
    if "kind" in view:
        kwargs["view"] = view.pop("kind")
    if "size" in view:
        kwargs["size"] = view.pop("size")
    if kwargs.get("view") == "camera":
        kwargs["camera"] = {k: view.pop(k) for k in CAMERA_KEYS if k in view}
    if "altitude_deg" in view or "azimuth_deg" in view:
        kwargs["directions"] = {k: view.pop(k) for k in DIRECTION_KEYS if k in view}


def _lights_keywords(lights: dict, base_dir: Path | None, kwargs: dict) -> None:
    """Move the keys of a TOML ``[lights]`` table into Scene keywords ``kwargs``.

    ``file`` (relative to ``base_dir``) is opened as the light map, ``synthetic_city`` builds
    one with :func:`skytorch.skyglow.citymap.synthetic_city`; ``observer_xy`` and ``lamp``
    stay; unknown keys stay in ``lights``.
    """
    if "file" in lights:
        path = Path(lights.pop("file"))
        if base_dir is not None and not path.is_absolute():
            path = base_dir / path
        if not path.exists():
            raise ValueError(f"scene: [lights] file {str(path)!r} does not exist")
        kwargs["light_map"] = open_dataset(path)
    if "synthetic_city" in lights:
        from skytorch.skyglow.citymap import synthetic_city

        options = lights.pop("synthetic_city")
        if not isinstance(options, Mapping):
            raise TypeError("scene: [lights] synthetic_city must be a table of keywords of "
                            f"skytorch.skyglow.citymap.synthetic_city; got {options!r:.60}")
        options = dict(options)
        if "centre_xy" in options:
            options["centre_xy"] = tuple(options["centre_xy"])
        kwargs["light_map"] = synthetic_city(**options)
    for key in ("observer_xy", "lamp"):
        if key in lights:
            kwargs[key] = lights.pop(key)


def _not_differentiable(name: str, value) -> None:
    """Refuse a tensor that asks for gradients rather than detach it silently.

    A scene reads its parameters as numbers.
    """
    if isinstance(value, torch.Tensor) and value.requires_grad:
        raise TypeError(
            f"{name}: a Scene is not differentiable (its components come from tables cached "
            "per parameter value); got a tensor that requires grad. Differentiate the tensor "
            "functions instead (e.g. Atmosphere.sky_radiance, skytorch.moon.magnitude)")


def _shape(value) -> tuple[int, ...]:
    try:
        return tuple(np.shape(value))
    except (TypeError, ValueError):
        return ()


def _scalar(name: str, value, low: float | None = None, high: float | None = None, *,
            unit: str = "") -> float:
    """Return a finite Python float (in ``[low, high]``) from a number-like value.

    From a number, numpy scalar or one-element tensor; ``TypeError``/``ValueError`` naming
    ``name`` otherwise.
    """
    if isinstance(value, bool) or value is None or isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be a number; got {value!r}")
    _not_differentiable(name, value)
    tensor = as_tensor(name, value)
    if tensor.numel() != 1:
        raise ValueError(
            f"{name} must be one number per scene; got shape {tuple(tensor.shape)} (scenes "
            "are not batched: render one scene per value, e.g. with skytorch.sweep)")
    return float(check_range(name, tensor.reshape(()), low, high, unit=unit))


def _wavelengths(value):
    """Return a wavelength preset name or a tuple of increasing wavelengths [nm].

    A preset name of :func:`skytorch.spectrum.wavelength_grid`, or a tuple of increasing wavelengths
    [nm] inside :data:`skytorch.spectrum.VISIBLE_RANGE_NM`.
    """
    from skytorch.spectrum import VISIBLE_RANGE_NM, WAVELENGTH_PRESETS

    if isinstance(value, str):
        return check_choice("wavelengths", value, WAVELENGTH_PRESETS)
    if value is None or isinstance(value, bytes):
        raise TypeError(f"wavelengths must be a preset {WAVELENGTH_PRESETS} or a sequence of "
                        f"wavelengths [nm]; got {value!r}")
    _not_differentiable("wavelengths", value)
    wavelength = check_range("wavelengths", value, *VISIBLE_RANGE_NM, unit=" nm")
    if wavelength.ndim > 1 or wavelength.numel() == 0:
        raise ValueError("wavelengths must be a 1-D sequence of at least one wavelength [nm]; "
                         f"got shape {tuple(wavelength.shape)}")
    wavelength = wavelength.reshape(-1)
    if bool((wavelength[1:] <= wavelength[:-1]).any()):
        raise ValueError(f"wavelengths must increase strictly; got {wavelength.tolist()}")
    return tuple(float(v) for v in wavelength)


def _orders(value):
    """Check ``scattering_orders``: "auto", "converged" or an integer >= 1."""
    if isinstance(value, str):
        return check_choice("scattering_orders", value, SCATTERING_ORDER_CHOICES)
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 1:
        return int(value)
    raise ValueError(f"scattering_orders must be an integer >= 1, 'converged' or 'auto'; "
                     f"got {value!r}")


def _effects(name: str, value, vocabulary) -> tuple[str, ...]:
    """Return a tuple of names from ``vocabulary``, given as a sequence or a comma-separated str."""
    if value is None:
        return ()
    if isinstance(value, str):
        names = tuple(v.strip() for v in value.split(",") if v.strip())
    elif isinstance(value, (Sequence, set, frozenset)) and not isinstance(value, bytes):
        names = tuple(value)
    else:
        raise TypeError(f"{name} must be a sequence of names from {tuple(vocabulary)} or a "
                        f"comma-separated string; got {value!r}")
    for item in names:
        check_choice(name, item, vocabulary)
    return names


def _numbers(name: str, value, low=None, high=None, unit: str = "") -> tuple[float, ...]:
    _not_differentiable(name, value)
    tensor = check_range(name, value, low, high, unit=unit)
    if tensor.ndim > 1 or tensor.numel() == 0:
        raise ValueError(f"{name} must be a number or a 1-D sequence of numbers; got shape "
                         f"{tuple(tensor.shape)}")
    return tuple(float(v) for v in tensor.reshape(-1))


def _directions(value) -> dict:
    """``{"altitude_deg": (...), "azimuth_deg": (...)}`` of one length.

    Altitudes in [0, 90] and finite azimuths [degree].
    """
    if not isinstance(value, Mapping):
        raise TypeError("directions must be a mapping {'altitude_deg': [...], 'azimuth_deg': "
                        f"[...]}} [degree]; got {type(value).__name__}")
    keys = set(value)
    if keys != set(DIRECTION_KEYS):
        raise ValueError(f"directions must have exactly the keys {DIRECTION_KEYS}; got "
                         f"{sorted(map(str, keys))}")
    altitude = _numbers("directions altitude_deg", value["altitude_deg"], 0.0, 90.0,
                        " degree")
    azimuth = _numbers("directions azimuth_deg", value["azimuth_deg"])
    if len(altitude) != len(azimuth):
        raise ValueError("directions: altitude_deg and azimuth_deg must have the same length; "
                         f"got {len(altitude)} and {len(azimuth)}")
    return {"altitude_deg": altitude, "azimuth_deg": azimuth}


def _camera(value) -> dict:
    """Return a camera mapping.

    ``fov_deg`` and either ``target`` or ``altitude_deg`` and ``azimuth_deg`` (checked).
    """
    if not isinstance(value, Mapping):
        raise TypeError("camera must be a mapping {'fov_deg': ..., 'target': 'moon'} or "
                        "{'fov_deg': ..., 'altitude_deg': ..., 'azimuth_deg': ...}; got "
                        f"{type(value).__name__}")
    unknown = sorted(map(str, set(value) - set(CAMERA_KEYS)))
    if unknown:
        raise ValueError(f"camera: unknown keys {unknown}; valid: {CAMERA_KEYS}")
    pointed = {"altitude_deg", "azimuth_deg"} & set(value)
    if "fov_deg" not in value or ("target" in value) == bool(pointed) or (
            pointed and len(pointed) != 2):
        raise ValueError("camera needs fov_deg and either target or both altitude_deg and "
                         f"azimuth_deg; got keys {sorted(map(str, value))}")
    low, high = CAMERA_FOV_RANGE_DEG
    camera = {"fov_deg": _scalar("camera fov_deg", value["fov_deg"], unit=" degree")}
    check_range("camera fov_deg", camera["fov_deg"], low, high, low_inclusive=False,
                unit=" degree")
    if "target" in value:
        camera["target"] = check_choice("camera target", value["target"], CAMERA_TARGETS)
    else:
        camera["altitude_deg"] = _scalar("camera altitude_deg", value["altitude_deg"], -90.0,
                                         90.0, unit=" degree")
        camera["azimuth_deg"] = _scalar("camera azimuth_deg", value["azimuth_deg"],
                                        unit=" degree")
    return camera


#: the keys of the TOML tables whose keys go straight to the Scene (docs/scene.md)
_TOML_TABLE_KEYS = {"observer": ("lat_deg", "lon_deg", "elevation_m"),
                    "atmosphere": ("turbidity", "ozone_du", "ground_albedo",
                                   "stratospheric_aod"),
                    "planner": ("tolerance", "fidelity", "scattering_orders", "force",
                                "exclude")}
#: 10.7 cm solar flux of a scene's airglow (natural_model="leinert1998") [sfu]
DEFAULT_SOLAR_FLUX_SFU = 130.0
#: keys of a TOML scene outside its tables (docs/scene.md)
_TOML_TOP_LEVEL_KEYS = ("time", "wavelengths", "outputs", "star_limit_mag",
                        "natural_mag_arcsec2", "natural_model", "airglow_fraction",
                        "airglow_height_m", "solar_flux_sfu", "dtype")


@dataclass
class Scene:
    """A sky to render: observer, time, view, spectral grid, atmosphere, lights, tolerance.

    Parameters
    ----------
    time : str, datetime or datetime64
        UTC instant of the scene.
    lat_deg, lon_deg : float or sequence of float
        Geodetic latitude in [-90, 90] and east longitude in [-180, 360) of the observer
        [degree] (:func:`skytorch.ephemeris.check_observer`). Sequences (with
        ``elevation_m``, broadcast to one length) give several observers: the render then
        has a dimension ``observer`` (:func:`skytorch.scene.render.render_observers`),
        also for a sequence of one.
    elevation_m : float or sequence of float
        Observer height above the ellipsoid [m], inside the atmosphere: from 0 to its top
        (100 km) and below ``airglow_height_m``.
    view : {"fisheye", "panorama", "directions"}
        Image geometry (module docstring).
    size : int
        Pixels across a fisheye (``size × size``) or elevations of a panorama, 2 to
        :data:`MAX_SIZE`.
    directions : mapping, optional
        ``{"altitude_deg": [...], "azimuth_deg": [...]}`` for ``view="directions"``
        (altitudes in [0, 90] [degree], one azimuth per altitude).
    camera : mapping, optional
        For ``view="camera"``: ``fov_deg`` (field across [degree]) and either
        ``target`` (one of :data:`CAMERA_TARGETS`) or ``altitude_deg`` and ``azimuth_deg``
        of the centre; ``fov_deg`` in (0, 120].
    wavelengths : str or sequence of float
        A preset of :func:`skytorch.spectrum.wavelength_grid` ("rgb", "bands15",
        "cie5", "cie1") or strictly increasing wavelengths [nm] in 360–830 nm
        (:data:`skytorch.spectrum.VISIBLE_RANGE_NM`).
    turbidity, ozone_du : float
        Atmosphere parameters, checked by :meth:`skytorch.atmosphere.Atmosphere.earth`
        (turbidity >= 1, ozone >= 0 DU). One number each: scenes are not batched.
    ground_albedo : float
        Lambertian albedo of the ground around the observer, in [0, 1] (0: a black ground,
        the default; fresh snow 0.8-0.9, desert 0.3, grass and forest 0.05-0.2 in the
        visible). The ground's reflection of sunlight and moonlight, scattered back by the
        air, is light of order >= 2: it enters the sky through the multiple-scattering
        tables, so a non-zero albedo needs ``scattering_orders`` other than 1 (ValueError
        otherwise) and no solar eclipse in sight (its sky is a direct quadrature over a
        black ground: the render raises). City lights keep the skyglow model's own
        reflectance of the lit ground (Garstang's G = 0.15,
        :func:`skytorch.skyglow.kernel.emission_intensity`).
    stratospheric_aod : float
        Vertical optical depth at 550 nm of the stratospheric sulfate layer [1], in
        :data:`STRATOSPHERIC_AOD_RANGE` (LOWTRAN 7's background profile, sulfate Mie optics;
        :meth:`skytorch.atmosphere.Atmosphere.earth`). Default 0: no layer. The quiet
        stratosphere holds 0.004–0.007 (:func:`skytorch.eclipse.stratospheric_aod` of the
        year); it brightens the deep twilight's zenith by up to 0.2 mag
        (docs/multiple_scattering.md, "The stratospheric aerosol").
    light_map : xarray.Dataset, optional
        City lights (``flux`` [lm] on ``(y, x)`` [m] around the observer), see
        :meth:`skytorch.skyglow.SkyglowModel.render`.
    observer_xy : (float, float) or sequence of them
        Observer position in the light map's frame [m] (finite); one pair per observer,
        or one pair for all.
    lamp : str
        Lamp spectrum of the lights (:data:`skytorch.skyglow.lamps.LAMPS`).
    tolerance : float
        Largest relative change of the image's V-band flux (L1 over the pixels) an
        omitted effect may cause, in [0, 1]; see :mod:`skytorch.scene.planner`.
    fidelity : {"fast", "default", "reference"}
        Knob preset of the modules (:data:`skytorch.scene.planner.FIDELITY`).
    scattering_orders : {"auto", "converged"} or int
        Orders of scattering of the sunlit and moonlit sky: 1 (single scattering), an
        integer N >= 1 (orders 1..N), ``"converged"`` (the planner keeps the orders the
        tolerance needs, :mod:`skytorch.scene.planner`) or ``"auto"``, the fidelity
        preset's choice (1 for "fast", "converged" for "default" and "reference").
    force, exclude : sequence of str
        Effects always computed / never computed (planner vocabulary).
    outputs : sequence of str
        Any of "spectral", "xyz", "srgb", "v_mag".
    star_limit_mag : float
        Faintest catalogue star drawn [V mag], in [-30, 15] (the range of
        :func:`skytorch.stars.bright_stars`).
    natural_mag_arcsec2 : float
        Natural sky background at the zenith (airglow + zodiacal light + faint stars)
        [V mag arcsec^-2]; 22.0 after Falchi et al. (2016); in
        :data:`NATURAL_MAG_RANGE` (14–26).
    natural_model : {"garstang1989", "vanrhijn1921", "constant", "leinert1998"}
        Variation of the natural background with zenith distance (:data:`NATURAL_MODELS`,
        :func:`skytorch.scene.render.natural_component`): ``"garstang1989"`` (Garstang
        1989; Krisciunas & Schaefer 1991) brightens the airglow part towards the horizon by
        the van Rhijn (1921) factor and dims the whole by the V-band extinction of the
        atmosphere relative to the zenith (``natural_mag_arcsec2`` is the observed zenith
        value, extinction included); ``"vanrhijn1921"``, the van Rhijn factor without
        extinction; ``"constant"``, the zenith value everywhere; ``"leinert1998"``, the
        sky per direction from its parts (:func:`skytorch.scene.natural_sky.natural_component`:
        zodiacal light by ecliptic geometry, airglow at ``solar_flux_sfu``, the light of
        catalogue stars fainter than ``star_limit_mag``, which must lie in [−2, 10];
        ``natural_mag_arcsec2`` and ``airglow_fraction`` are not used and must keep their
        defaults, ValueError otherwise).
    solar_flux_sfu : float
        10.7 cm solar flux [sfu] setting the airglow level of ``natural_model="leinert1998"``
        (130: mean of a solar cycle), in :data:`SOLAR_FLUX_RANGE_SFU`.
    airglow_fraction : float
        Share of the zenith background emitted by the airglow layer (0.6, Garstang 1989;
        Patat 2003), in [0, 1]; the rest comes from beyond the atmosphere and is uniform.
    airglow_height_m : float
        Height of the emitting airglow layer [m] (90 km: the OI 557.7 nm, Na and OH
        layers at 85–100 km, Leinert et al. 1998), in [10 km, 1000 km].
    dtype : torch.dtype
        Floating type of the computation (float32 or float64).

    Raises
    ------
    TypeError
        A parameter of the wrong type (naming it), an unknown keyword, or a tensor that
        requires grad.
    ValueError
        A value outside its range, a tensor of more than one element (scenes are not
        batched: render one scene per value, e.g. with :func:`skytorch.sweep`), or
        inconsistent parameters (naming them).

    Notes
    -----
    Gradients: a Scene is not differentiable. Its parameters are read as numbers and key
    the tables of its :class:`~skytorch.scene.resources.SceneResources` (atmosphere,
    transmittance, refraction and extinction tables, the skyglow model) and its sky and
    moonlit-sky look-up tables, the Sun and Moon come from skyfield,
    and the result is a Dataset of numpy arrays; a tensor parameter that requires grad is
    refused rather than silently detached. The tensor functions the components are built
    from carry gradients (e.g. :meth:`skytorch.atmosphere.Atmosphere.sky_radiance`,
    :func:`skytorch.moon.magnitude`, :func:`skytorch.scene.render.natural_gradient`).
    """

    time: object = "2015-09-28T02:47:00"
    lat_deg: float = 52.52
    lon_deg: float = 13.40
    elevation_m: float = 0.0
    view: str = "fisheye"
    size: int = 256
    directions: Mapping | None = None
    camera: Mapping | None = None
    wavelengths: object = "rgb"
    turbidity: float = 2.0
    ozone_du: float = 300.0
    ground_albedo: float = 0.0
    stratospheric_aod: float = 0.0
    light_map: object = None
    observer_xy: tuple = (0.0, 0.0)
    lamp: str = "white"
    tolerance: float = 0.01
    fidelity: str = "default"
    scattering_orders: object = "auto"
    force: Sequence[str] = field(default_factory=tuple)
    exclude: Sequence[str] = field(default_factory=tuple)
    outputs: Sequence[str] = ("spectral", "xyz", "srgb", "v_mag")
    star_limit_mag: float = 6.5
    natural_mag_arcsec2: float = NATURAL_ZENITH_SKY_MAG_ARCSEC2
    natural_model: str = "garstang1989"
    airglow_fraction: float = DEFAULT_AIRGLOW_FRACTION
    airglow_height_m: float = 90_000.0
    solar_flux_sfu: float = DEFAULT_SOLAR_FLUX_SFU
    dtype: torch.dtype = torch.float64
    #: the resources of the scene this one was copied from (``dataclasses.replace`` passes
    #: them on); kept when their spec is this scene's, else new ones are made
    _resources: SceneResources | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):  # noqa: C901 (a flat list of per-field checks)
        """Check every field and store it normalised (TypeError/ValueError naming it)."""
        from skytorch.ephemeris import parse_times

        self.time = parse_times(self.time)
        if self.time.shape != (1,):
            raise ValueError(f"time: one instant per scene; got {self.time.size}")
        self.time = self.time[0]
        check_choice("view", self.view, VIEWS)
        if isinstance(self.size, (torch.Tensor, np.ndarray)) and np.size(self.size) != 1:
            raise ValueError(f"size must be one number per scene; got shape "
                             f"{tuple(np.shape(self.size))}")
        self.size = check_int("size", self.size, 2, MAX_SIZE)
        check_choice("fidelity", self.fidelity, FIDELITY_PRESETS)
        check_choice("natural_model", self.natural_model, NATURAL_MODELS)
        self.scattering_orders = _orders(self.scattering_orders)
        if not isinstance(self.dtype, torch.dtype) or self.dtype not in (torch.float32,
                                                                          torch.float64):
            raise TypeError(f"dtype must be torch.float32 or torch.float64; got {self.dtype!r}")
        # the atmosphere's own checks (Atmosphere.earth): one definition of its ranges
        self.turbidity = _scalar("turbidity", self.turbidity)
        self.ozone_du = _scalar("ozone_du", self.ozone_du)
        self.ground_albedo = _scalar("ground_albedo", self.ground_albedo, 0.0, 1.0)
        self.stratospheric_aod = _scalar("stratospheric_aod", self.stratospheric_aod,
                                         *STRATOSPHERIC_AOD_RANGE)
        if self.ground_albedo > 0.0 and requested_orders(self) == 1:
            raise ValueError(
                f"ground_albedo={self.ground_albedo} needs the orders of scattering >= 2 (the "
                "ground's light reaches the sky by scattering once more); the scene's "
                f"scattering_orders={self.scattering_orders!r} with fidelity "
                f"{self.fidelity!r} is single scattering: give scattering_orders='converged' "
                "or ground_albedo=0")
        self.wavelengths = _wavelengths(self.wavelengths)
        spec = SceneSpec.of(self)
        if not (isinstance(self._resources, SceneResources) and self._resources.spec == spec):
            if self._resources is not None and not isinstance(self._resources, SceneResources):
                raise TypeError("_resources must be a SceneResources or None; got "
                                f"{type(self._resources).__name__}")
            self._resources = SceneResources(spec)
        atmosphere = self._resources.atmosphere
        self.tolerance = _scalar("tolerance", self.tolerance, 0.0, 1.0)
        self.star_limit_mag = _scalar("star_limit_mag", self.star_limit_mag,
                                      *STAR_LIMIT_RANGE_MAG, unit=" mag")
        self.natural_mag_arcsec2 = _scalar("natural_mag_arcsec2", self.natural_mag_arcsec2,
                                           *NATURAL_MAG_RANGE, unit=" mag arcsec-2")
        self.airglow_fraction = _scalar("airglow_fraction", self.airglow_fraction, 0.0, 1.0)
        self.airglow_height_m = _scalar("airglow_height_m", self.airglow_height_m,
                                        *AIRGLOW_HEIGHT_RANGE_M, unit=" m")
        self.solar_flux_sfu = _scalar("solar_flux_sfu", self.solar_flux_sfu,
                                      *SOLAR_FLUX_RANGE_SFU, unit=" sfu")
        self._observers(atmosphere)
        self.force = _effects("force", self.force, EFFECTS)
        self.exclude = _effects("exclude", self.exclude, EFFECTS)
        self.outputs = _effects("outputs", self.outputs, OUTPUTS)
        both = set(self.force) & set(self.exclude)
        if both:
            raise ValueError(f"force and exclude both name {sorted(both)}")
        if self.natural_model == "leinert1998":
            self._leinert_settings()
        elif self.solar_flux_sfu != DEFAULT_SOLAR_FLUX_SFU:
            raise ValueError(f"solar_flux_sfu={self.solar_flux_sfu!r}: used by "
                             f"natural_model='leinert1998' only (the airglow's solar cycle); "
                             f"got natural_model={self.natural_model!r}")
        if not self.outputs:
            raise ValueError(f"outputs must name at least one of {list(OUTPUTS)}; got none")
        for name, kind in (("directions", "directions"), ("camera", "camera")):
            if getattr(self, name) is not None and self.view != kind:
                raise ValueError(f"{name} describes view='{kind}'; got view={self.view!r} "
                                 f"(its {name} would be ignored)")
        if self.directions is not None:
            self.directions = _directions(self.directions)
        elif self.view == "directions":
            raise ValueError("view='directions' needs directions={'altitude_deg': [...], "
                             "'azimuth_deg': [...]}")
        if self.camera is not None:
            self.camera = _camera(self.camera)
        elif self.view == "camera":
            raise ValueError("view='camera' needs camera={'fov_deg': ..., 'target': 'moon'} "
                             "or {'fov_deg': ..., 'altitude_deg': ..., 'azimuth_deg': ...}")
        self._lights()

    def _lights(self) -> None:
        """Check the light map and lamp (the observer positions in ``_observers``)."""
        import xarray as xr

        from skytorch.skyglow.lamps import LAMPS

        check_choice("lamp", self.lamp, LAMPS)
        if self.light_map is None:
            unused = [f"{name}={value!r}" for name, value, default in (
                ("lamp", self.lamp, "white"), ("observer_xy", self.observer_xy, (0.0, 0.0)))
                if value != default]
            if unused:
                raise ValueError(f"{', '.join(unused)}: settings of the light map's skyglow; "
                                 "the scene has no light_map")
            return
        if not isinstance(self.light_map, xr.Dataset):
            raise TypeError("light_map must be an xarray.Dataset with a variable 'flux' [lm] "
                            f"on (y, x), or None; got {type(self.light_map).__name__}")
        if "flux" not in self.light_map.data_vars or not {"y", "x"} <= set(
                self.light_map["flux"].dims):
            raise ValueError("light_map must hold a variable 'flux' [lm] on dimensions (y, x); "
                             f"got variables {sorted(self.light_map.data_vars)}")
        # the fluxes and coordinates too (NaN or negative flux), before a plan is made
        from skytorch.skyglow.model import light_map_arrays

        light_map_arrays(self.light_map)

    def _leinert_settings(self) -> None:
        """Check the settings of ``natural_model="leinert1998"`` (ValueError naming them).

        The map of the catalogue's fainter stars spans
        :data:`skytorch.nightsky.starlight.FAINTER_THAN_RANGE_MAG`; the zenith value and the
        airglow share of the other models are not used (the planner takes the darkest
        natural sky, 22.0, as its bound).
        """
        from skytorch.nightsky.starlight import FAINTER_THAN_RANGE_MAG

        low, high = FAINTER_THAN_RANGE_MAG
        if not low <= self.star_limit_mag <= high:
            raise ValueError(f"star_limit_mag must be in [{low:g}, {high:g}] mag with "
                             "natural_model='leinert1998' (the catalogue map of the fainter "
                             f"stars); got {self.star_limit_mag:g} mag")
        unused = [f"{name}={getattr(self, name)!r}" for name, default in (
            ("natural_mag_arcsec2", NATURAL_ZENITH_SKY_MAG_ARCSEC2),
            ("airglow_fraction", DEFAULT_AIRGLOW_FRACTION)) if getattr(self, name) != default]
        if unused:
            raise ValueError(f"{', '.join(unused)}: not used by natural_model='leinert1998', "
                             "which computes the sky per direction from its parts")

    # ------------------------------------------------------------------ observers
    def _observers(self, atmosphere) -> None:
        """Validate the observers.

        Broadcast sequences of coordinates to tuples of one length (scalars stay floats).

        Latitude, longitude and height go through the ephemeris' observer check
        (:func:`skytorch.ephemeris.check_observer`); the height must also lie inside the
        scene's atmosphere, [0, ``top_altitude_m``] (the range of
        :meth:`skytorch.atmosphere.Atmosphere.sky_radiance`), and below the airglow layer.
        """
        from skytorch.ephemeris import check_observer

        for name in ("lat_deg", "lon_deg", "elevation_m"):
            _not_differentiable(name, getattr(self, name))
        lat, lon, height = check_observer(self.lat_deg, self.lon_deg, self.elevation_m)
        if lat.ndim > 1 or lat.numel() == 0:
            raise ValueError("lat_deg, lon_deg, elevation_m: scalars or 1-D sequences of at "
                             f"least one observer; got shapes {_shape(self.lat_deg)}, "
                             f"{_shape(self.lon_deg)}, {_shape(self.elevation_m)}")
        check_range("elevation_m", height, 0.0, atmosphere.top_altitude_m,
                    unit=" m")
        highest = float(height.max())
        if highest >= self.airglow_height_m:
            raise ValueError(f"elevation_m must be below airglow_height_m "
                             f"({self.airglow_height_m} m); got {highest} m")
        several = lat.ndim == 1
        if several:
            self.lat_deg, self.lon_deg, self.elevation_m = (
                tuple(float(x) for x in v) for v in (lat, lon, height))
        else:
            self.lat_deg, self.lon_deg, self.elevation_m = (float(v)
                                                            for v in (lat, lon, height))
        _not_differentiable("observer_xy", self.observer_xy)
        pairs = check_finite("observer_xy", self.observer_xy)
        if pairs.shape == (2,):
            self.observer_xy = (float(pairs[0]), float(pairs[1]))
        elif several and pairs.shape == (len(self.lat_deg), 2):
            self.observer_xy = tuple((float(x), float(y)) for x, y in pairs.tolist())
        else:
            count = len(self.lat_deg) if several else 1
            raise ValueError(f"observer_xy: one (x, y) pair [m], or one per observer "
                             f"({count}); got shape {tuple(pairs.shape)}")

    @property
    def n_observers(self) -> int:
        """Number of observers (1 for scalar coordinates)."""
        return len(self.lat_deg) if isinstance(self.lat_deg, tuple) else 1

    @property
    def several_observers(self) -> bool:
        """Whether the observers were given as sequences.

        The render then has a dimension ``observer``, even of length one.
        """
        return isinstance(self.lat_deg, tuple)

    def observers(self) -> list[Scene]:
        """One-observer scenes, one per observer (the scene itself for one observer)."""
        if not isinstance(self.lat_deg, tuple):
            return [self]
        pairs = np.asarray(self.observer_xy, dtype=float)
        return [self.replace(lat_deg=lat, lon_deg=lon, elevation_m=height,
                             observer_xy=tuple(pairs[i]) if pairs.ndim == 2
                             else self.observer_xy)
                for i, (lat, lon, height) in enumerate(zip(self.lat_deg, self.lon_deg,
                                                           self.elevation_m, strict=True))]

    # ------------------------------------------------------------------ pieces
    def wavelength_nm(self) -> torch.Tensor:
        """Return the scene's wavelength grid (n_wavelength,) [nm]."""
        from skytorch.spectrum import wavelength_grid

        if isinstance(self.wavelengths, str):
            return wavelength_grid(self.wavelengths, dtype=self.dtype)
        return torch.as_tensor(np.asarray(self.wavelengths, dtype=float), dtype=self.dtype)

    def make_view(self, resources: SceneResources | None = None) -> View:
        """Return the :class:`View` of the scene.

        ``resources``, default :meth:`resources`, keep the fisheye and panorama views, shared by
        renders: do not modify their tensors; a camera aimed at the Sun or Moon reads their places
        from them.
        """
        if self.view in ("fisheye", "panorama"):
            make = fisheye_view if self.view == "fisheye" else panorama_view
            return self._checked(resources).view(self.view, self.size, self.dtype,
                                                 lambda: make(self.size, self.dtype))
        if self.view == "camera":
            return camera_view(*self.camera_centre(resources), self.camera["fov_deg"],
                               self.size, self.dtype)
        return directions_view(self.directions["altitude_deg"], self.directions["azimuth_deg"],
                               self.dtype)

    def camera_centre(self, resources: SceneResources | None = None) -> tuple[float, float]:
        """Altitude and azimuth [degree] of a camera view's centre.

        Given, or the apparent (refracted) place of its target (from ``resources``, default
        :meth:`resources`); a target far below the horizon (below −1° and the refraction
        table's lowest true altitude) at its true place.
        """
        if "target" not in self.camera:
            return float(self.camera["altitude_deg"]), float(self.camera["azimuth_deg"])
        resources = self._checked(resources)
        g = resources.geometry(self)
        body = self.camera["target"]
        altitude = getattr(g, f"{body}_altitude_deg")
        table = resources.refraction_table(float(self.elevation_m))
        if math.radians(altitude) < min(math.radians(-1.0), float(table["low_rad"])):
            # below the refraction table (and the apparent horizon): its true place (the
            # table would give the horizon's refraction, a camera aimed at the horizon)
            return altitude, getattr(g, f"{body}_azimuth_deg")
        apparent = math.degrees(resources.refracted_altitude(float(self.elevation_m),
                                                             math.radians(altitude)))
        return apparent, getattr(g, f"{body}_azimuth_deg")

    def resources(self) -> SceneResources:
        """Return the scene's :class:`~skytorch.scene.resources.SceneResources`.

        Built with the scene, filled by its plans and renders, and shared with the copies of
        :meth:`replace` and :meth:`observers` that keep its spec (keep it to render a time series).
        """
        return self._resources

    def _checked(self, resources: SceneResources | None) -> SceneResources:
        if resources is None:
            return self._resources
        if not isinstance(resources, SceneResources):
            raise TypeError("resources must be a skytorch.scene.SceneResources "
                            f"(Scene.resources()) or None; got {type(resources).__name__}")
        resources.check(self)
        return resources

    def atmosphere(self):
        """Return the scene's :class:`skytorch.atmosphere.Atmosphere` (held by its resources)."""
        return self._resources.atmosphere

    def replace(self, **changes) -> Scene:
        """Return a copy with some fields changed.

        It shares this scene's resources when its spec (turbidity, ozone, wavelengths) is the same.
        """
        return replace(self, **changes)

    def parameters(self) -> dict:  # noqa: C901 (one branch per field type)
        """Return the scene's parameters as netCDF-safe values (Dataset attributes)."""
        out = {}
        for f in fields(self):
            if f.name == "_resources":
                continue
            value = getattr(self, f.name)
            if f.name == "light_map":
                value = "none" if value is None else "given"
            elif f.name == "time":
                value = str(value)[:26]
            elif f.name == "dtype":
                value = str(value).replace("torch.", "")
            elif f.name == "wavelengths" and not isinstance(value, str):
                value = [float(v) for v in np.asarray(value).reshape(-1)]
            elif f.name in ("force", "exclude", "outputs"):
                value = ",".join(value)
            elif f.name == "directions":
                value = "none" if value is None else "given"
            elif f.name == "camera":
                value = "none" if value is None else json.dumps(dict(value), sort_keys=True)
            elif f.name == "observer_xy":
                value = [float(v) for v in np.asarray(value, dtype=float).reshape(-1)]
            elif isinstance(value, tuple):
                value = list(value)
            out[f.name] = value
        return out

    # ------------------------------------------------------------------ actions
    def plan(self, resources: SceneResources | None = None):
        """Decide the effects to compute (:func:`skytorch.scene.planner.plan`).

        A list of plans, one per observer, for several observers (their Sun and Moon from one
        ephemeris evaluation). ``resources`` default to :meth:`resources`.
        """
        resources = self._checked(resources)
        if not self.several_observers:
            return make_plan(self, resources=resources)
        geometries = resources.geometries(self.time, self.lat_deg, self.lon_deg,
                                          self.elevation_m)
        return [make_plan(scene, resources=resources, geometry=g)
                for scene, g in zip(self.observers(), geometries, strict=True)]

    def render(self, plan=None, resources: SceneResources | None = None):
        """Render the scene to a Dataset (:func:`skytorch.scene.render.render`).

        With its own resources or the given ones (``ValueError`` when their spec differs).
        """
        return render_scene(self, plan, resources)

    # ------------------------------------------------------------------ TOML
    @classmethod
    def from_dict(cls, config: Mapping, base_dir: Path | None = None) -> Scene:
        """Build a scene from a mapping (the TOML scene format, see ``docs/scene.md``).

        Tables ``[observer]`` (lat_deg, lon_deg, elevation_m), ``[view]`` (kind, size,
        altitude_deg, azimuth_deg; for a camera also fov_deg and target),
        ``[atmosphere]`` (turbidity, ozone_du, ground_albedo, stratospheric_aod), ``[lights]``
        (``file`` = a netCDF light map, or ``synthetic_city`` = keyword table of
        :func:`skytorch.skyglow.citymap.synthetic_city`; observer_xy, lamp),
        ``[planner]`` (tolerance, fidelity, scattering_orders, force, exclude) and top-level time,
        wavelengths, outputs, star_limit_mag, natural_mag_arcsec2.
        """
        if not isinstance(config, Mapping):
            raise TypeError(f"config must be a mapping (a parsed TOML scene); got "
                            f"{type(config).__name__}")
        config = dict(config)
        tables = ("observer", "view", "atmosphere", "planner", "lights")
        # a table's key at the top level would override the table (and no file says so)
        stray = sorted(set(config) - set(tables) - set(_TOML_TOP_LEVEL_KEYS))
        if stray:
            raise ValueError(f"scene: unknown top-level keys {stray}; valid: "
                             f"{list(_TOML_TOP_LEVEL_KEYS)} and the tables "
                             f"{['[' + name + ']' for name in tables]}")
        kwargs: dict = {}

        def table(name: str) -> dict:
            value = config.pop(name, {})
            if not isinstance(value, Mapping):
                raise TypeError(f"scene: [{name}] must be a table; got {value!r:.60}")
            value = dict(value)
            # a key in another table is not silently taken (docs/scene.md's format)
            allowed = _TOML_TABLE_KEYS.get(name)
            stray = sorted(set(value) - set(allowed)) if allowed is not None else []
            if stray:
                raise ValueError(f"scene: unknown keys {stray} in [{name}]; valid: "
                                 f"{list(allowed)}")
            return value

        def no_leftovers(name: str, rest: dict) -> None:
            if rest:
                raise ValueError(f"scene: unknown keys {sorted(rest)} in [{name}]")

        kwargs.update(table("observer"))
        view = table("view")
        _view_keywords(view, kwargs)
        no_leftovers("view", view)
        kwargs.update(table("atmosphere"))
        kwargs.update(table("planner"))
        lights = table("lights")
        _lights_keywords(lights, base_dir, kwargs)
        no_leftovers("lights", lights)
        if "dtype" in config:
            kwargs["dtype"] = {"float64": torch.float64, "float32": torch.float32}[
                check_choice("dtype", config.pop("dtype"), ("float64", "float32"))]
        kwargs.update(config)
        names = {f.name for f in fields(cls)} - {"_resources"}
        unknown = sorted(set(kwargs) - names)
        if unknown:
            raise ValueError(f"scene: unknown keys {unknown}; valid: {sorted(names)}")
        return cls(**kwargs)

    @classmethod
    def from_toml(cls, path) -> Scene:
        """Read a scene from a TOML file (format in ``docs/scene.md``)."""
        path = Path(path)
        config = toml_loads(path.read_text(encoding="utf-8"))
        # a file names its instant and place (Scene()'s defaults, the 2015-09-28 eclipse
        # over Berlin, would otherwise stand in for a forgotten key)
        observer = config.get("observer")
        missing = ([] if "time" in config else ["time"]) + [
            f"[observer] {key}" for key in ("lat_deg", "lon_deg")
            if not isinstance(observer, Mapping) or key not in observer]
        scene = cls.from_dict(config, base_dir=path.parent)  # unknown keys first
        if missing:
            raise ValueError(f"scene file {str(path)!r} must give {', '.join(missing)}")
        return scene
