r"""The constituents of an atmosphere at given wavelengths: the one interface to every kernel.

:meth:`skytorch.atmosphere.Atmosphere.constituents` returns a :class:`Constituents`, an
immutable value object holding, per species by name (a :class:`Species`):

* its vertical **profile** (a :class:`Profile`): the density relative to a reference
  density as a pure function of altitude, callable on tensors, with the quadrature
  **breakpoints** (profile kinks, layer peaks) and the column height
  :math:`\int_0^{top}\rho\,dh`;
* its **extinction** and **scattering** coefficients at the reference density
  (``(*batch, wavelength)`` [1/m], batched over the atmosphere's parameters), hence its
  **single-scattering albedo**;
* a **phase-function** handle (``None`` for pure absorbers);
* an optional **nonlinear law** :math:`\tau = f(u)` of its path column :math:`u` (band
  models with a curve of growth); linear species have :math:`\tau = k\,u`.

Every optical depth in skytorch is computed from per-species PATH COLUMNS through one
method, :meth:`Constituents.optical_depth`: straight rays
(:meth:`Constituents.column_integrals`), refracted rays (columns integrated along the bent
path), the view path of single scattering (cumulative columns along the samples), the
eclipse shadow and the skyglow kernel all hand their columns to it, so a species with a
nonlinear law is right along every path, including refracted limb paths.

Shapes and alignment
--------------------
Parameters have the atmosphere's batch shape ``B``; geometry tensors broadcast with
``B`` and may carry ``extra`` further dims after it (e.g. the samples along a view ray).
Every method that combines the two takes ``extra`` explicitly (never held as state, so
one :class:`Constituents` or :class:`Atmosphere` can be shared by threads): batched
tensors of the constituents get ``extra`` singleton dims inserted after their batch dims.

Adding a species
----------------
A species is registered in :data:`skytorch.atmosphere.model.SPECIES_BUILDERS` (a tuple,
one :class:`SpeciesBuilder` line per species, in output order) with two pure functions
of the atmosphere's parameters:

* ``profile(atmosphere, dtype) -> Profile``: its relative density versus altitude;
* ``build(atmosphere, wavelength_nm, dtype, profile) -> Species``: its coefficients at
  the checked 1-D ``wavelength_nm`` (in ``dtype``), phase function and law;
* optionally ``absent(atmosphere) -> bool``: True where its amount is exactly zero and
  needs no gradient (its columns are then not integrated).

A new parameter of the species is a keyword of :class:`~skytorch.atmosphere.Atmosphere`
(add it to ``_PARAMETERS``, ``PARAMETER_RANGES`` and the constructor's signature; it
becomes a float64 buffer, ``atmosphere.<name>``, batched like the others; read it cast
to ``dtype``). Nothing else changes: every kernel (optical depth, refraction, single
scattering, shadow, skyglow) sees the species through :class:`Constituents`. Worked
example: a uniformly mixed absorber following the molecules with a curve-of-growth law
:math:`\tau = S(\lambda)\sqrt{u}` of its column :math:`u = N_{ref}\int\rho\,ds`
[m^-2] (a nonlinear law: only the path column is used, so it is right along refracted
paths as well):

>>> import torch
>>> from skytorch.atmosphere import Atmosphere
>>> from skytorch.atmosphere.constituents import Species, SpeciesBuilder, insert_dims
>>> def band_profile(atmosphere, dtype):
...     return atmosphere.profiles(dtype)["rayleigh"]      # mixed like the air
>>> def band_species(atmosphere, wavelength_nm, dtype, profile):
...     # reference number density [m^-3], shape (*B)
...     n_ref = atmosphere.molecular_column_m2(dtype) / profile.column_height_m
...     strength = 1e-16 * torch.exp(-((wavelength_nm - 760.0) / 2.0) ** 2)  # [m]
...     def law(column, extra):                 # column (*B', *extra) [m]
...         u = column * insert_dims(n_ref, extra, 0)       # [m^-2]
...         return torch.sqrt(u)[..., None] * strength
...     return Species("toy_band", profile, extinction=torch.zeros_like(strength), law=law)
>>> builder = SpeciesBuilder("toy_band", band_profile, band_species)
>>> atm = Atmosphere.earth(ozone_du=0.0, aerosol_optical_depth=0.0)
>>> c = atm.constituents(torch.tensor([700.0, 760.0], dtype=torch.float64),
...                      extra_species=(builder,))
>>> columns = c.column_integrals(torch.tensor(6_371_000.0, dtype=torch.float64),
...                              torch.tensor(1.0, dtype=torch.float64))
>>> tau = c.optical_depth(columns, per_species=True)
>>> bool(tau["toy_band"][0] < 1e-6 < tau["toy_band"][1])
True
>>> bool(torch.allclose(c.optical_depth(columns), sum(tau.values())))
True

In the library the two functions live in the species' own module (e.g.
``skytorch/atmosphere/gases.py``) and its builder is listed in ``SPECIES_BUILDERS``
(``extra_species`` is for experiments); every kernel then sees the species without
further change (its density by :meth:`Constituents.densities`, its scattering by
:meth:`Constituents.scatterers`). A species whose ``scattering`` is not ``None`` must
give a ``phase``.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere import Atmosphere
>>> c = Atmosphere.earth(turbidity=2.0).constituents(torch.tensor([550.0]))
>>> c.names
('rayleigh', 'aerosol', 'ozone', 'stratospheric_aerosol', 'h2o', 'o2', 'o2o2')
>>> c["ozone"].phase is None    # pure absorber
True
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import torch

from skytorch._validate import broadcast_shape
from skytorch.atmosphere import optical_depth as _od

__all__ = ["CHUNK", "Constituents", "Profile", "Species", "SpeciesBuilder", "column_integrals",
           "insert_dims"]

#: rays per chunk in column integrals of unbatched parameters (the per-ray temporaries; the
#: nodes are evaluated in smaller blocks, see optical_depth.NODE_BLOCK_BYTES)
CHUNK = 16384


def insert_dims(tensor: torch.Tensor, extra: int, core: int) -> torch.Tensor:
    """``tensor`` of shape ``(*B, *core_dims)`` with ``extra`` singleton dims after ``B``.

    Parameters
    ----------
    tensor : Tensor (*B, *core_dims)
        ``core`` trailing dims (e.g. 1 for a spectrum) after the batch dims ``B``.
    extra, core : int
        Number of singleton dims to insert and of trailing core dims.

    Returns
    -------
    Tensor
        ``(*B, 1, ..., 1, *core_dims)``; unchanged when ``B`` is empty (an unbatched
        tensor broadcasts against anything) or ``extra`` is 0.
    """
    if extra == 0 or tensor.ndim <= core:
        return tensor
    shape = tuple(tensor.shape)
    split = len(shape) - core
    return tensor.reshape(shape[:split] + (1,) * extra + shape[split:])


def _frozen(mapping: Mapping[str, torch.Tensor]) -> Mapping[str, torch.Tensor]:
    return MappingProxyType(dict(mapping))


@dataclass(frozen=True)
class Profile:
    r"""A vertical profile: relative density as a pure function of altitude.

    Parameters
    ----------
    function : callable
        ``function(altitude_m, **parameters)`` -> relative density [1], same shape as
        ``altitude_m``; pure, differentiable, broadcasting its parameters.
    parameters : mapping of str to Tensor (*B)
        Keyword arguments of ``function`` (batch-shaped or 0-d).
    breakpoints_m : Tensor (*B, n_level), optional
        Increasing absolute altitudes [m] where the integrand changes character (kinks,
        layer boundaries, peaks); the path quadrature cuts its pieces there.
    relative_breakpoints_m : Tensor (*B, n_level), optional
        Breakpoints counted from the lowest altitude of each leg of a path (exponential
        profiles: multiples of the scale height, so that the relative accuracy does not
        depend on the observer's altitude). Exactly one of the two is given.
    column_height_m : Tensor (*B)
        :math:`\int_0^{top}\rho(h)\,dh` [m]: a vertical column of the species is its
        reference density times this height.
    truncate : bool
        The last breakpoint ends the path integrals (negligible density above).
    support : bool
        The density vanishes outside [first, last breakpoint] (only that range is
        integrated).
    aloft : bool
        The density peaks above the ground (a layer, e.g. stratospheric aerosol): tables
        over tangent altitude split their nodes at its breakpoints
        (:func:`skytorch.eclipse.shadow_scattering.impact_nodes`).
    state, from_state : callable, optional
        Given together: the density as ``from_state(state(altitude_m), **parameters)``,
        equal to ``function(altitude_m, **parameters)``. ``state`` is a pure function of
        the altitude alone (e.g. :func:`skytorch.atmosphere.profiles.us1976_state`, the
        layers of a standard atmosphere) returning a tuple of tensors shaped like
        ``altitude_m``; profiles naming the same ``state`` function and the same
        quadrature (breakpoints, ``truncate``, ``support``) are integrated on one set of
        nodes where the state is evaluated once for all of them.
    piecewise_state : bool
        ``state`` takes a second argument, an altitude in the same layer as (broadcasting
        against) the first (:func:`skytorch.atmosphere.profiles.us1976_state`), and the
        breakpoints include every layer boundary of the state: along a path the layer is
        then looked up once per quadrature piece (at its middle) instead of at every node.
    """

    function: Callable[..., torch.Tensor]
    parameters: Mapping[str, torch.Tensor]
    column_height_m: torch.Tensor
    breakpoints_m: torch.Tensor | None = None
    relative_breakpoints_m: torch.Tensor | None = None
    truncate: bool = False
    support: bool = False
    aloft: bool = False
    state: Callable[[torch.Tensor], tuple] | None = None
    from_state: Callable[..., torch.Tensor] | None = None
    piecewise_state: bool = False

    def __post_init__(self):
        """Check that exactly one kind of breakpoints is given."""
        if (self.breakpoints_m is None) == (self.relative_breakpoints_m is None):
            raise ValueError("a Profile takes exactly one of breakpoints_m and "
                             "relative_breakpoints_m")
        if (self.state is None) != (self.from_state is None):
            raise ValueError("a Profile takes state and from_state together (or neither)")
        if self.piecewise_state and (self.state is None or self.breakpoints_m is None):
            raise ValueError("piecewise_state needs a state and absolute breakpoints_m")
        object.__setattr__(self, "parameters", _frozen(self.parameters))

    def __call__(self, altitude_m: torch.Tensor, extra: int = 0) -> torch.Tensor:
        """Relative density at ``altitude_m`` (*B', *extra, n_sample) [1], same shape.

        ``altitude_m`` has the batch dims, ``extra`` geometry dims and one sample dim.
        """
        parameters = {key: insert_dims(value, extra + 1, 0)
                      for key, value in self.parameters.items()}
        return self.function(altitude_m, **parameters)

    def _evaluate(self, altitude_m: torch.Tensor, extra: int, states: dict) -> torch.Tensor:
        """:meth:`__call__`, taking the state from (or adding it to) ``states``.

        A dict by state function of the states already evaluated at this ``altitude_m``.
        """
        if self.state is None:
            return self(altitude_m, extra)
        state = states.get(self.state)
        if state is None:
            state = states[self.state] = self.state(altitude_m)
        parameters = {key: insert_dims(value, extra + 1, 0)
                      for key, value in self.parameters.items()}
        return self.from_state(state, **parameters)

    def _same_quadrature(self, other: Profile) -> bool:
        """Whether ``other`` has the same quadrature pieces along every path.

        Same pieces: equal breakpoints (constants, not needing a gradient), ``truncate``,
        ``support`` and ``piecewise_state``.
        """
        if ((self.truncate, self.support, self.piecewise_state)
                != (other.truncate, other.support, other.piecewise_state)):
            return False
        for mine, theirs in ((self.breakpoints_m, other.breakpoints_m),
                             (self.relative_breakpoints_m, other.relative_breakpoints_m)):
            if (mine is None) != (theirs is None):
                return False
            if mine is None or mine is theirs:
                continue
            if (mine.requires_grad or theirs.requires_grad or mine.shape != theirs.shape
                    or mine.dtype != theirs.dtype or not torch.equal(mine, theirs)):
                return False
        return True

    def levels(self, extra: int = 0):
        """Breakpoints for :func:`skytorch.atmosphere.optical_depth.column_integral`.

        A tensor (*B, *extra, n_level) of absolute altitudes, or a function of the lowest
        altitude of each leg (shape (*B', *extra)) returning them.
        """
        if self.breakpoints_m is not None:
            return insert_dims(self.breakpoints_m, extra, 1)
        offsets = insert_dims(self.relative_breakpoints_m, extra, 1)
        return lambda base: base[..., None] + offsets


@dataclass(frozen=True)
class Species:
    r"""One constituent: profile, spectral coefficients, phase function, optical-depth law.

    Parameters
    ----------
    name : str
        Key of the species (``per_species`` outputs, Datasets).
    profile : Profile
        Its relative density versus altitude.
    extinction : Tensor (*B, wavelength)
        Extinction coefficient where the relative density is 1 [1/m] (absorption plus
        scattering). For a species with a nonlinear ``law`` it is the coefficient used
        where a local value is needed (e.g. zero, or the weak-line limit) and may be
        zero.
    scattering : Tensor (*B, wavelength), optional
        Scattering coefficient where the relative density is 1 [1/m]; ``None`` for a pure
        absorber.
    phase : callable, optional
        ``phase(cos_theta, extra=0)``: with ``cos_theta`` (*B', *extra) the phase function
        [1/sr] normalised over 4π, shape (*B', *extra, wavelength) or (*B', *extra, 1);
        required when ``scattering`` is given.
    law : callable, optional
        ``law(column, extra)``: with the path column ``column`` (*B', *extra) [m] the
        optical depth (*B', *extra, wavelength) [1]. ``None``: linear,
        :math:`\tau = k_{ext}\,u`.
    law_indices : Tensor (band,) of int64, optional
        With ``law``: the wavelength indices where the law can be nonzero (a band); the
        law then returns the optical depth at those wavelengths only
        (*B', *extra, band), and zero elsewhere is implied.
    vanishes : bool
        The species is exactly absent (a zero amount that needs no gradient): its
        columns are zero without integration.
    """

    name: str
    profile: Profile
    extinction: torch.Tensor
    scattering: torch.Tensor | None = None
    phase: Callable[..., torch.Tensor] | None = None
    law: Callable[[torch.Tensor, int], torch.Tensor] | None = None
    law_indices: torch.Tensor | None = None
    vanishes: bool = False

    def __post_init__(self):
        """Check the species' fields (TypeError/ValueError naming the field)."""
        if not isinstance(self.name, str) or not self.name:
            raise TypeError(f"a species name must be a non-empty string; got {self.name!r}")
        if self.scattering is not None and self.phase is None:
            raise ValueError(f"species {self.name!r} scatters but has no phase function")
        if self.law_indices is not None and self.law is None:
            raise ValueError(f"species {self.name!r} has law_indices but no law")

    @property
    def single_scattering_albedo(self) -> torch.Tensor:
        """Scattering over extinction (*B, wavelength) [1].

        0 for pure absorbers and where the extinction is zero.
        """
        if self.scattering is None:
            return torch.zeros_like(self.extinction)
        safe = torch.where(self.extinction > 0, self.extinction,
                           torch.ones_like(self.extinction))
        return torch.where(self.extinction > 0, self.scattering / safe,
                           torch.zeros_like(self.extinction))

    def optical_depth(self, column: torch.Tensor, extra: int = 0) -> torch.Tensor:
        """Optical depth (*B', *extra, wavelength) [1] of the path column (*B', *extra) [m]."""
        if self.law is None:
            return column[..., None] * insert_dims(self.extinction, extra, 1)
        return self._spectrum(self.law(column, extra))

    def _spectrum(self, tau: torch.Tensor) -> torch.Tensor:
        """Return the law's optical depth ``tau`` at every wavelength (zero outside the band)."""
        if self.law_indices is None:
            return tau
        return tau.new_zeros(*tau.shape[:-1], self.extinction.shape[-1]).index_copy(
            -1, self.law_indices, tau)


@dataclass(frozen=True)
class SpeciesBuilder:
    """How an :class:`~skytorch.atmosphere.Atmosphere` builds one species.

    Parameters
    ----------
    name : str
        The species' name (key of ``per_species`` outputs).
    profile : callable
        ``profile(atmosphere, dtype) -> Profile``.
    build : callable
        ``build(atmosphere, wavelength_nm, dtype, profile) -> Species`` with the checked
        1-D ``wavelength_nm`` in ``dtype`` and the species' ``profile``.
    absent : callable, optional
        ``absent(atmosphere) -> bool``: the amount is exactly zero and needs no gradient.
    """

    name: str
    profile: Callable
    build: Callable
    absent: Callable | None = None


def column_integrals(profiles: Mapping[str, Profile], r, mu, planet_radius_m: float,
                     top_radius_m: float, *, method: str = "gauss",
                     n_steps: int | None = None, rtol: float = 1e-9, extra: int = 0,
                     vanishing: tuple[str, ...] = (), batch_shape: tuple = ()
                     ) -> dict[str, torch.Tensor]:
    r"""Path columns :math:`\int\rho_s\,ds` [m] of each profile along straight rays.

    Parameters
    ----------
    profiles : mapping of str to Profile
        The species' profiles.
    r, mu : Tensor (*B', *extra)
        Radius of the ray origins [m] and cosine of their zenith angle [1].
    planet_radius_m, top_radius_m : float
        Radii of the ground and of the top of the atmosphere [m].
    method, n_steps, rtol
        Quadrature (:func:`skytorch.atmosphere.optical_depth.column_integral`).
    extra : int
        Geometry dims after the batch dims.
    vanishing : tuple of str
        Species whose columns are zero (not integrated).
    batch_shape : tuple
        Batch shape of the parameters; without batch dims large ray sets are integrated
        in chunks of :data:`CHUNK` rays, their nodes in blocks of
        :data:`skytorch.atmosphere.optical_depth.NODE_BLOCK_BYTES`.

    Returns
    -------
    dict of Tensor (*broadcast)
        One column per profile [m].
    """
    shape = broadcast_shape(r.shape, mu.shape)
    count = math.prod(shape)
    if tuple(batch_shape) == () and count > CHUNK:
        r_flat = r.expand(shape).reshape(-1)
        mu_flat = mu.expand(shape).reshape(-1)
        pieces = [column_integrals(profiles, r_flat[i:i + CHUNK], mu_flat[i:i + CHUNK],
                                   planet_radius_m, top_radius_m, method=method,
                                   n_steps=n_steps, rtol=rtol, vanishing=vanishing)
                  for i in range(0, count, CHUNK)]
        return {name: torch.cat([piece[name] for piece in pieces]).reshape(shape)
                for name in profiles}
    # unbatched parameters: the nodes may be evaluated in cache-sized blocks of rays
    block_bytes = _od.NODE_BLOCK_BYTES if tuple(batch_shape) == () else None
    legs = _od.crossing_legs(r, mu, planet_radius_m, top_radius_m)  # shared by the groups
    columns = {}
    for group in _quadrature_groups(profiles, vanishing, method):
        first = profiles[group[0]]
        values = _od.column_integral(
            _group_density(tuple(profiles[name] for name in group), extra), r, mu,
            planet_radius_m, top_radius_m, first.levels(extra), method=method,
            n_steps=n_steps, rtol=rtol, truncate=first.truncate, support=first.support,
            block_bytes=block_bytes, legs=legs, piecewise=first.piecewise_state)
        columns.update(zip(group, values if len(group) > 1 else (values,), strict=True))
    columns = {name: columns[name] for name in profiles if name in columns}
    if vanishing:
        reference = next(iter(columns.values())) if columns else 0.0 * (r * mu)
        for name in vanishing:
            columns[name] = torch.zeros_like(reference)
        columns = {name: columns[name] for name in profiles}
    return columns


def _group_density(members: tuple[Profile, ...], extra: int):
    """Return the density callable of profiles integrated on the same nodes.

    ``density(altitude_m, piece_altitude_m=None)``: the relative density of one profile, or
    a tuple of them, at ``altitude_m`` (..., n_sample). With ``piece_altitude_m``
    (:attr:`Profile.piecewise_state`), ``altitude_m`` is (..., piece, node) and the states
    are looked up once per piece; the densities come back flattened to (..., piece * node).
    """
    def density(altitude_m, piece_altitude_m=None):
        states = {}  # each state evaluated once on these nodes
        if piece_altitude_m is not None:
            for profile in members:
                if profile.state is not None and profile.state not in states:
                    states[profile.state] = tuple(
                        value.reshape(*value.shape[:-2], -1)
                        for value in profile.state(altitude_m, piece_altitude_m))
            altitude_m = altitude_m.reshape(*altitude_m.shape[:-2], -1)
        values = tuple(profile._evaluate(altitude_m, extra, states) for profile in members)
        return values if len(members) > 1 else values[0]

    return density


def _accumulate(total, owned: bool, species: Species, column: torch.Tensor, extra: int):
    """Add the optical depth of ``species`` to ``total``; return it and whether it is owned.

    ``owned``: ``total`` is a tensor of this sum's own, updated in place where the term fits
    its shape and dtype.
    """
    if species.law is None and owned:
        coefficient = insert_dims(species.extinction, extra, 1)
        if _fits(total, column.shape + (1,), coefficient.shape,
                 dtype=torch.promote_types(column.dtype, coefficient.dtype)):
            return total.addcmul_(column[..., None], coefficient), True
    if species.law_indices is not None and owned:
        band = species.law(column, extra)
        if _fits(total, band.shape[:-1] + (1,), dtype=band.dtype):
            return total.index_add_(-1, species.law_indices,
                                    band.expand(*total.shape[:-1], band.shape[-1])), True
        return total + species._spectrum(band), True
    value = species.optical_depth(column, extra)
    if total is None:
        return value, False
    if owned and _fits(total, value.shape, dtype=value.dtype):
        return total.add_(value), True
    return total + value, True


def _fits(total: torch.Tensor, *shapes, dtype: torch.dtype) -> bool:
    """Whether terms of ``shapes`` and ``dtype`` add into ``total`` in place.

    They broadcast to its shape and do not promote its dtype.
    """
    if torch.promote_types(total.dtype, dtype) != total.dtype:
        return False
    try:
        return tuple(broadcast_shape(total.shape, *shapes)) == tuple(total.shape)
    except ValueError:
        return False


def _quadrature_groups(profiles: Mapping[str, Profile], vanishing: tuple[str, ...],
                       method: str) -> list[tuple[str, ...]]:
    """Names of the profiles to integrate together, in order of first appearance.

    With ``"gauss"`` the profiles of the same quadrature share their nodes (each keeps
    exactly the pieces it had alone) and, where they name one :attr:`Profile.state`, its
    evaluation; with ``"adaptive"`` (which refines each column on its own) and
    ``"trapezoid"`` every profile is integrated alone.
    """
    groups: list[list[str]] = []
    for name, profile in profiles.items():
        if name in vanishing:
            continue
        if method == "gauss":
            for group in groups:
                if profiles[group[0]]._same_quadrature(profile):
                    group.append(name)
                    break
            else:
                groups.append([name])
        else:
            groups.append([name])
    return [tuple(group) for group in groups]


@dataclass(frozen=True)
class Constituents:
    """Every species of an atmosphere at given wavelengths (immutable).

    Parameters
    ----------
    wavelength_nm : Tensor (wavelength,)
        Wavelengths [nm] of the spectral coefficients.
    species : tuple of Species
        The species, in output order (names unique).
    planet_radius_m, top_radius_m : float
        Radii of the ground and of the top of the atmosphere [m].
    batch_shape : torch.Size
        Batch shape of the atmosphere's parameters.

    Notes
    -----
    Built by :meth:`skytorch.atmosphere.Atmosphere.constituents`; every kernel takes it
    as an argument. It holds no mutable state and may be shared between threads.
    """

    wavelength_nm: torch.Tensor
    species: tuple[Species, ...]
    planet_radius_m: float
    top_radius_m: float
    batch_shape: torch.Size = field(default_factory=torch.Size)

    def __post_init__(self):
        """Store the species as a tuple of unique names and the batch shape as a Size."""
        species = tuple(self.species)
        names = [s.name for s in species]
        if len(set(names)) != len(names):
            raise ValueError(f"species names must be unique; got {names}")
        object.__setattr__(self, "species", species)
        object.__setattr__(self, "batch_shape", torch.Size(self.batch_shape))

    # ------------------------------------------------------------------ access
    @property
    def names(self) -> tuple[str, ...]:
        """Species names, in output order."""
        return tuple(s.name for s in self.species)

    @property
    def dtype(self) -> torch.dtype:
        """Floating dtype of the wavelengths and the results."""
        return self.wavelength_nm.dtype

    @property
    def top_altitude_m(self) -> float:
        """Altitude of the top of the atmosphere [m]."""
        return self.top_radius_m - self.planet_radius_m

    def __getitem__(self, name: str) -> Species:
        """Return the species called ``name`` (KeyError listing the species otherwise)."""
        for species in self.species:
            if species.name == name:
                return species
        raise KeyError(f"no species {name!r}; species: {', '.join(self.names)}")

    def __contains__(self, name) -> bool:
        """Whether a species is called ``name``."""
        return name in self.names

    @property
    def profiles(self) -> dict[str, Profile]:
        """The profile of each species, by name."""
        return {s.name: s.profile for s in self.species}

    def scatterers(self) -> tuple[Species, ...]:
        """Return the species that scatter (``scattering`` not None)."""
        return tuple(s for s in self.species if s.scattering is not None)

    # ------------------------------------------------------------------ columns
    def column_integrals(self, r, mu, *, method: str = "gauss", n_steps: int | None = None,
                         rtol: float = 1e-9, extra: int = 0) -> dict[str, torch.Tensor]:
        """Path columns [m] of every species along straight rays from radius ``r`` [m].

        With zenith cosine ``mu`` (*B', *extra) (see :func:`column_integrals`).
        """
        return column_integrals(self.profiles, r, mu, self.planet_radius_m, self.top_radius_m,
                                method=method, n_steps=n_steps, rtol=rtol, extra=extra,
                                vanishing=tuple(s.name for s in self.species if s.vanishes),
                                batch_shape=self.batch_shape)

    def densities(self, altitude_m: torch.Tensor, extra: int = 0) -> dict[str, torch.Tensor]:
        """Relative density of every species at ``altitude_m`` (*B', *extra, n_sample).

        A :attr:`Profile.state` shared by several species evaluated once.
        """
        states = {}
        return {s.name: s.profile._evaluate(altitude_m, extra, states) for s in self.species}

    # ------------------------------------------------------------------ optical depth
    def optical_depth(self, columns: Mapping[str, torch.Tensor], *, per_species: bool = False,
                      extra: int = 0):
        r"""Optical depth of per-species path columns: the one place where columns become τ.

        Parameters
        ----------
        columns : mapping of str to Tensor (*B', *extra)
            Path column :math:`\int\rho_s\,ds` [m] of every species (straight,
            refracted or partial paths alike).
        per_species : bool
            Return a dict by species name instead of the total.
        extra : int
            Geometry dims of the columns after the batch dims.

        Returns
        -------
        Tensor (*B', *extra, wavelength) or dict of them
            Optical depth [1]; the dict's values (each broadcast to the total's shape)
            sum to the total.
        """
        missing = [name for name in self.names if name not in columns]
        if missing:
            raise ValueError(f"columns lack species {missing}; every species of "
                             f"{list(self.names)} needs its path column")
        if per_species:
            result = {s.name: s.optical_depth(columns[s.name], extra) for s in self.species}
            # every species with the shape of the total (Dataset-ready; views, no copies)
            return dict(zip(result, torch.broadcast_tensors(*result.values()), strict=True))
        # the sum accumulated in place in a tensor of its own: linear species with
        # unbatched spectra as one matrix product, others as column x coefficient (in species
        # order), species with a band law added at their band's wavelengths only
        total, owned, rest = self._linear_product(columns), True, self.species
        if total is None:
            owned = False
        else:
            rest = tuple(s for s in self.species if s.law is not None)
        for s in rest:
            total, owned = _accumulate(total, owned, s, columns[s.name], extra)
        return total

    def _linear_product(self, columns: Mapping[str, torch.Tensor]) -> torch.Tensor | None:
        """Optical depth of the linear species as one matrix product, or None.

        None unless their spectra are 1-D (unbatched) and their columns share shape and
        dtype with the spectra.
        """
        linear = [s for s in self.species if s.law is None]
        if not linear or any(s.extinction.ndim != 1 for s in linear):
            return None
        stack = [columns[s.name] for s in linear]
        if (len({(c.shape, c.dtype) for c in stack}) != 1
                or stack[0].dtype != linear[0].extinction.dtype):
            return None
        return torch.stack(stack, -1) @ torch.stack([s.extinction for s in linear])


    # ------------------------------------------------------------------ local coefficients
    def extinction_coefficients(self, altitude_m: torch.Tensor, extra: int = 0
                                ) -> dict[str, torch.Tensor]:
        """Local extinction coefficient of every species (*B', *extra, n_sample, wavelength) [1/m].

        At ``altitude_m`` (*B', *extra, n_sample): the linear coefficient times the density; a
        species with a nonlinear law contributes its ``extinction``.
        """
        states = {}
        return {s.name: s.profile._evaluate(altitude_m, extra, states)[..., None]
                * insert_dims(s.extinction, extra + 1, 1) for s in self.species}

    def scattering_coefficients(self, altitude_m: torch.Tensor, extra: int = 0
                                ) -> dict[str, torch.Tensor]:
        """Local scattering coefficient of the scattering species [1/m].

        Shape (*B', *extra, n_sample, wavelength).
        """
        states = {}
        return {s.name: s.profile._evaluate(altitude_m, extra, states)[..., None]
                * insert_dims(s.scattering, extra + 1, 1) for s in self.scatterers()}
