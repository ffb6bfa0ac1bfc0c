"""5-sigma limiting magnitude of one ZTF exposure: science image (D1), difference image (D2).

A transient is found in the difference between the exposure and ZTF's
reference image of the field, so the limit a plan reaches is that of the
difference image.  Three numbered steps (``docs/design/detection.md`` §2):

**(D1) science image.**  Sky-background-limited point source, aperture ∝
FWHM², sky flux ``10^(-0.4 mu)`` per arcsec²::

    m_sci = C_b + 1.25 log10(t / 30 s) + 0.5 (mu_b - mu_dark,b)
            - k_b (X - 1) - 2.5 log10(FWHM_b(X) / FWHM_zen,b),   FWHM_b(X) = FWHM_zen,b X^0.6

``C_b``: depth of 30 s at the zenith on a dark night; ``mu_b``: sky surface
brightness towards the field; ``k_b``: extinction (mag per airmass); the
seeing degrades as X^0.6 (Kolmogorov; ztf_sim's ``seeing_at_pointing`` uses
the same law).  ZTF is sky limited from 30 s up (r: ~130 sky e-/s/pixel
against ~10 e- read noise), so the ``1.25 log10 t`` scaling holds.

**(D2) difference image.**  The difference has the broader of the two PSFs
(the sharper image is matched to the other) and the noise of both images::

    FWHM_D = max(FWHM_b(X), FWHM_ref,b)
    m_diff = -1.25 log10( 10^(-0.8 m_sci') + 10^(-0.8 m_ref') )
    m_sci' = m_sci - 2.5 log10(FWHM_D / FWHM_b(X)),   m_ref' = m_ref,b - 2.5 log10(FWHM_D / FWHM_ref,b)

with ZTF's own reference images (O3-era, ``gwemopt_ZTF.ref``: median over
quadrants of ``maglimcat`` g 22.82, r 22.69, i 22.20 and of ``fwhmmed`` g
2.39", r 2.27", i 2.23"; GPL-3.0 data, numbers only).  At 30 s the
reference costs ~0.01 mag and the PSF matching ~0.15; at 300 s the reference
costs ~0.12 mag: longer exposures gain less than ``1.25 log10 t``.

**(D3) exposure time and the guider.**  ZTF exposures longer than 300 s
need the guider (ZTF technical page); guided, the PSF does not degrade, so
(D1)-(D2) apply unchanged up to gwemopt's ``max_exposure`` of 600 s; what
limits the gain of a long exposure is the reference term of (D2).

Sky brightness (flux sum of three terms, per band):

* **Dark sky**, airglow brightening towards the horizon (Krisciunas &
  Schaefer 1991, PASP 103, 1033, "K&S", eq. 2 with X of their eq. 3).
* **Moonlight**, K&S eqs. 15-21 (phase, Rayleigh + Mie scattering at the
  Moon-field separation, extinction of moonlight and the scattering column),
  with each band's extinction and the Sun's colours (AB, Willmer 2018:
  g - V = +0.31, r - V = -0.15, i - V = -0.27).
* **Twilight**: with the Sun between -18 deg and the horizon, extra sky
  ``B_dark,zen (10^(0.4 s (h_sun + 18)) - 1)``, ``s = 2.5/6`` mag/deg (Tyson
  & Gal 1993; Patat et al. 2006).

Calibration.  ``C_b`` makes the median of (D1) over a year of ZTF-like
pointings (random night times, Sun < -12 deg, airmass <= 2, Moon >= 20 deg
away, all phases) equal ZTF's published median science-image depths in
30 s: g 20.8, r 20.6, i 19.9 (Bellm et al. 2019, PASP 131, 018002; Masci et
al. 2019, PASP 131, 018003); ``FWHM_zen`` makes the median seeing over the
same pointings (median X^0.6 = 1.195) ZTF's median image quality, 2.0" in r
(Bellm et al. 2019), g and i scaled as λ^-0.2.  (D2) then adds no free
parameter: its 30 s medians (g 20.66, r 20.46) are a prediction, to be set
against the published difference-image depths in 30 s (ZTF technical
specification 20.4 in R; gwemopt's ZTF config r 20.4; GCN Circ. 25418
"typical depth of ~20.5").  ``docs/design/detection.md`` §2.1 has the table
against every published figure, the GW campaigns included;
``tests/scheduler/test_depth.py`` repeats it.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np
from astropy import units as u
from astropy.coordinates import TETE, EarthLocation, SkyCoord
from astropy.time import Time

from ..sky.ephemeris import ephemeris
from ..sky.visibility import site

__all__ = [
    "ZTF_MEDIAN_DEPTH_30S",
    "SkyConditions",
    "DepthModel",
    "ZTF_DEPTH",
    "depth_model",
    "sky_conditions",
    "dark_zenith",
    "sky_brightness",
    "seeing_fwhm",
    "science_depth",
    "limiting_magnitude",
]

#: ZTF's published median 5-sigma depths (AB mag) of a 30 s exposure.
ZTF_MEDIAN_DEPTH_30S: Mapping[str, float] = {"g": 20.8, "r": 20.6, "i": 19.9}

#: K&S eq. 3 constant (airmass of a thin layer at height ~ 10 km).
_KS_AIRMASS = 0.96
#: Sun colours (AB) relative to V, for the colour of moonlight (Willmer 2018).
_SUN_MINUS_V: Mapping[str, float] = {"g": 0.31, "r": -0.15, "i": -0.27}


@dataclass(frozen=True)
class SkyConditions:
    """Where an exposure points and what the sky does there (arrays broadcast).

    Attributes
    ----------
    airmass : numpy.ndarray
        Airmass of the field, sec z (>= 1).
    moon_alt_deg : numpy.ndarray
        Altitude of the Moon (deg).
    moon_sep_deg : numpy.ndarray
        Angular distance from the field to the Moon (deg).
    moon_phase_deg : numpy.ndarray
        Moon phase angle (deg): 0 full, 180 new.
    sun_alt_deg : numpy.ndarray
        Altitude of the Sun (deg).
    """

    airmass: np.ndarray
    moon_alt_deg: np.ndarray
    moon_sep_deg: np.ndarray
    moon_phase_deg: np.ndarray
    sun_alt_deg: np.ndarray


def dark_zenith(shape: tuple[int, ...] = ()) -> SkyConditions:
    """Zenith on a dark night: Moon set and new, Sun far below the horizon."""
    return SkyConditions(
        airmass=np.ones(shape), moon_alt_deg=np.full(shape, -30.0), moon_sep_deg=np.full(shape, 180.0),
        moon_phase_deg=np.full(shape, 180.0), sun_alt_deg=np.full(shape, -30.0),
    )


def sky_conditions(ra_deg: np.ndarray, dec_deg: np.ndarray, times: Time,
                   location: tuple[float, float, float] | None = None) -> SkyConditions:
    """Airmass, Moon and Sun for pointings seen from Palomar (or ``location``).

    Parameters
    ----------
    ra_deg, dec_deg : array_like
        Pointing centres (deg, ICRS).
    times : astropy.time.Time
        Times of the exposures; broadcasts against ``ra_deg`` (e.g. fields
        ``(n, 1)`` against slot times ``(m,)`` gives ``(n, m)`` conditions).
    location : tuple of float, optional
        (latitude deg, longitude deg, height m) of another site (a
        :class:`DepthModel`'s ``location``); default the P48's.

    Returns
    -------
    SkyConditions
        Arrays of the broadcast shape.  The Sun and the Moon come from the
        shared ephemeris (:func:`~..sky.ephemeris.ephemeris`: astropy at
        10 min nodes, interpolated, E1-E3); field altitudes follow in
        closed form from the local apparent sidereal time and the fields'
        apparent place (as in :mod:`.visibility`), so a whole field-by-slot grid costs a few
        astropy calls, not one per pointing.
    """
    ra = np.asarray(ra_deg, float)
    dec = np.asarray(dec_deg, float)
    loc = site() if location is None else _location(location)
    sky = ephemeris(times, loc)  # (E1-E3): the Sun, the Moon and the sidereal time, as the constraints read them
    jd = np.asarray(times.utc.jd, float)
    mid = Time(0.5 * (float(jd.min()) + float(jd.max())), format="jd", scale="utc")
    flat_ra, flat_dec = np.broadcast_arrays(ra, dec)
    app = SkyCoord(ra=flat_ra.ravel() * u.deg, dec=flat_dec.ravel() * u.deg, frame="icrs").transform_to(TETE(obstime=mid))
    ra_app = app.ra.deg.reshape(flat_ra.shape)
    dec_app = np.radians(app.dec.deg.reshape(flat_ra.shape))
    lat = np.radians(loc.lat.deg)
    ha = np.radians(sky.lst_deg - ra_app)
    sin_alt = np.sin(lat) * np.sin(dec_app) + np.cos(lat) * np.cos(dec_app) * np.cos(ha)
    airmass = np.where(sin_alt > 1e-3, 1.0 / np.maximum(sin_alt, 1e-3), np.inf)
    mra, mdec = np.radians(sky.moon_ra_deg), np.radians(sky.moon_dec_deg)
    fra, fdec = np.radians(ra), np.radians(dec)
    cos_sep = np.sin(fdec) * np.sin(mdec) + np.cos(fdec) * np.cos(mdec) * np.cos(fra - mra)
    sep = np.degrees(np.arccos(np.clip(cos_sep, -1.0, 1.0)))
    shape = np.broadcast_shapes(ra.shape, dec.shape, jd.shape)
    return SkyConditions(airmass=np.broadcast_to(airmass, shape), moon_alt_deg=np.broadcast_to(sky.moon_alt_deg, shape),
                         moon_sep_deg=np.broadcast_to(sep, shape),
                         moon_phase_deg=np.broadcast_to(sky.moon_phase_deg, shape),
                         sun_alt_deg=np.broadcast_to(sky.sun_alt_deg, shape))


@functools.lru_cache(maxsize=8)
def _location(where: tuple[float, float, float]) -> EarthLocation:
    lat, lon, height = where
    return EarthLocation.from_geodetic(lon=lon * u.deg, lat=lat * u.deg, height=height * u.m)


@dataclass(frozen=True)
class DepthModel:
    """Parameters of (D1) and of the sky model, per band.

    Attributes
    ----------
    dark_zenith_depth_30s : mapping
        ``C_b``: 5-sigma depth (AB) of a 30 s exposure at the zenith, dark sky.
    dark_sky_zenith : mapping
        Zenith night-sky brightness (mag/arcsec²) without Moon or twilight.
    extinction : mapping
        ``k_b`` (mag per airmass).
    seeing_airmass_exponent : float
        FWHM ∝ X^exponent (0.6 for Kolmogorov turbulence).
    twilight_slope_mag_per_deg : float
        ``s``: how fast the twilight sky fades with the Sun's depression.
    zenith_fwhm_arcsec : mapping
        ``FWHM_zen,b``: seeing at the zenith (arcsec), (D1).
    reference_depth : mapping
        ``m_ref,b``: 5-sigma depth (AB) of ZTF's reference images, (D2).
    reference_fwhm_arcsec : mapping
        ``FWHM_ref,b``: seeing of the reference images (arcsec), (D2).
    sun_minus_v : mapping
        Colour of sunlight, band minus V (mag): the colour of moonlight.
    location : tuple of float or None
        (latitude deg, longitude deg, height m) of the telescope whose depth
        this is (:func:`sky_conditions`); None: the P48's.
    """

    dark_zenith_depth_30s: Mapping[str, float] = field(default_factory=lambda: {"g": 21.52, "r": 21.25, "i": 20.43})
    dark_sky_zenith: Mapping[str, float] = field(default_factory=lambda: {"g": 21.8, "r": 21.0, "i": 20.2})
    extinction: Mapping[str, float] = field(default_factory=lambda: {"g": 0.17, "r": 0.10, "i": 0.05})
    seeing_airmass_exponent: float = 0.6
    twilight_slope_mag_per_deg: float = 2.5 / 6.0
    zenith_fwhm_arcsec: Mapping[str, float] = field(default_factory=lambda: {"g": 1.77, "r": 1.67, "i": 1.61})
    reference_depth: Mapping[str, float] = field(default_factory=lambda: {"g": 22.82, "r": 22.69, "i": 22.20})
    reference_fwhm_arcsec: Mapping[str, float] = field(default_factory=lambda: {"g": 2.39, "r": 2.27, "i": 2.23})
    sun_minus_v: Mapping[str, float] = field(default_factory=lambda: dict(_SUN_MINUS_V))
    location: tuple[float, float, float] | None = None

    def _per_band(self, table: Mapping[str, float], bands: np.ndarray) -> np.ndarray:
        missing = sorted(set(bands.ravel().tolist()) - set(table))
        if missing:
            raise ValueError(f"depth model has no band {', '.join(missing)} (bands: {', '.join(table)})")
        uniq, inv = np.unique(bands, return_inverse=True)
        return np.array([float(table[b]) for b in uniq.tolist()], dtype=float)[inv].reshape(bands.shape)


#: The default model, calibrated to ZTF's median depths (see module notes).
ZTF_DEPTH = DepthModel()


def _ks_airmass(airmass: np.ndarray) -> np.ndarray:
    """K&S eq. 3 airmass from sec z (saturates near the horizon)."""
    cos_z = 1.0 / np.maximum(np.asarray(airmass, float), 1.0)
    sin2 = 1.0 - cos_z ** 2
    return 1.0 / np.sqrt(1.0 - _KS_AIRMASS * sin2)


def _nl_to_mag(b_nl: np.ndarray) -> np.ndarray:
    """nanoLamberts to V mag/arcsec² (K&S eq. 1 inverse)."""
    with np.errstate(divide="ignore"):
        return (20.7233 - np.log(np.asarray(b_nl, float) / 34.08)) / 0.92104


def _moon_nl(cond: SkyConditions, k: np.ndarray) -> np.ndarray:
    """Scattered moonlight (nanoLamberts) towards each field (K&S eqs. 15-21)."""
    alpha = np.abs(np.asarray(cond.moon_phase_deg, float))
    illum = 10.0 ** (-0.4 * (3.84 + 0.026 * alpha + 4e-9 * alpha ** 4))
    rho = np.clip(np.asarray(cond.moon_sep_deg, float), 0.5, 180.0)
    f_rho = 10.0 ** 5.36 * (1.06 + np.cos(np.radians(rho)) ** 2) + 10.0 ** (6.15 - rho / 40.0)
    moon_alt = np.asarray(cond.moon_alt_deg, float)
    x_moon = _ks_airmass(1.0 / np.maximum(np.sin(np.radians(np.maximum(moon_alt, 0.0))), 1e-3))
    x_sky = _ks_airmass(cond.airmass)
    b = f_rho * illum * 10.0 ** (-0.4 * k * x_moon) * (1.0 - 10.0 ** (-0.4 * k * x_sky))
    return np.where(moon_alt > 0.0, b, 0.0)


def sky_brightness(bands: np.ndarray, cond: SkyConditions, model: DepthModel = ZTF_DEPTH) -> np.ndarray:
    """Sky surface brightness towards each field (mag/arcsec², AB).

    Parameters
    ----------
    bands : array_like of str
        Filter of each exposure (``g``, ``r``, ``i``).
    cond : SkyConditions
        Conditions broadcasting against ``bands``.
    model : DepthModel
        Sky parameters.

    Returns
    -------
    numpy.ndarray
        ``mu_b``: dark sky (airglow brightening with airmass) + moonlight +
        twilight, as magnitudes per arcsec².
    """
    bands = np.asarray(bands, dtype=str)
    k = model._per_band(model.extinction, bands)
    mu_dark = model._per_band(model.dark_sky_zenith, bands)
    colour = model._per_band(model.sun_minus_v, bands)
    x = np.asarray(cond.airmass, float)
    xks = _ks_airmass(x)
    dark = 10.0 ** (-0.4 * mu_dark) * 10.0 ** (-0.4 * k * (xks - 1.0)) * xks
    moon = 10.0 ** (-0.4 * (_nl_to_mag(np.maximum(_moon_nl(cond, k), 1e-30)) + colour))
    h = np.asarray(cond.sun_alt_deg, float)
    tw_ratio = np.where(h > -18.0, 10.0 ** (0.4 * model.twilight_slope_mag_per_deg * (np.minimum(h, 0.0) + 18.0)) - 1.0,
                        0.0)
    twilight = 10.0 ** (-0.4 * mu_dark) * tw_ratio
    return -2.5 * np.log10(dark + moon + twilight)


def seeing_fwhm(bands: np.ndarray, airmass: np.ndarray, model: DepthModel = ZTF_DEPTH) -> np.ndarray:
    """Seeing FWHM (arcsec) of exposures at airmass ``airmass``: ``FWHM_zen,b X^0.6`` (D1)."""
    bands = np.asarray(bands, dtype=str)
    x = np.maximum(np.asarray(airmass, float), 1.0)
    return model._per_band(model.zenith_fwhm_arcsec, bands) * x ** model.seeing_airmass_exponent


def science_depth(bands: np.ndarray, exposure_s: np.ndarray, cond: SkyConditions,
                  model: DepthModel = ZTF_DEPTH) -> np.ndarray:
    """5-sigma limiting magnitude (AB) of the science image, equation (D1).

    Parameters
    ----------
    bands : array_like of str
        Filter of each exposure.
    exposure_s : array_like
        Exposure times (s).
    cond : SkyConditions
        Conditions of each exposure (e.g. :func:`sky_conditions`), broadcasting.
    model : DepthModel
        Calibrated parameters; default :data:`ZTF_DEPTH`.

    Returns
    -------
    numpy.ndarray
        Limiting magnitude (mag); ``-inf`` below the horizon.
    """
    bands = np.asarray(bands, dtype=str)
    c = model._per_band(model.dark_zenith_depth_30s, bands)
    k = model._per_band(model.extinction, bands)
    mu_dark = model._per_band(model.dark_sky_zenith, bands)
    mu = sky_brightness(bands, cond, model)
    x = np.asarray(cond.airmass, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        m5 = (c + 1.25 * np.log10(np.asarray(exposure_s, float) / 30.0) + 0.5 * (mu - mu_dark)
              - k * (x - 1.0) - 2.5 * model.seeing_airmass_exponent * np.log10(x))
    return np.where(np.isfinite(x), m5, -np.inf)


def limiting_magnitude(bands: np.ndarray, exposure_s: np.ndarray, cond: SkyConditions,
                       model: DepthModel = ZTF_DEPTH) -> np.ndarray:
    """5-sigma limiting magnitude (AB) of the difference image, equation (D2).

    The depth a transient search reaches: the science image of (D1) against
    ZTF's reference, at the broader of the two PSFs.  Parameters and the
    returned array (mag; ``-inf`` below the horizon) as :func:`science_depth`.
    """
    bands = np.asarray(bands, dtype=str)
    m_sci = science_depth(bands, exposure_s, cond, model)
    fwhm = seeing_fwhm(bands, np.where(np.isfinite(cond.airmass), cond.airmass, 1.0), model)
    fwhm_ref = model._per_band(model.reference_fwhm_arcsec, bands)
    fwhm_d = np.maximum(fwhm, fwhm_ref)
    m_sci_d = m_sci - 2.5 * np.log10(fwhm_d / fwhm)
    m_ref_d = model._per_band(model.reference_depth, bands) - 2.5 * np.log10(fwhm_d / fwhm_ref)
    with np.errstate(over="ignore"):
        m5 = -1.25 * np.log10(10.0 ** (-0.8 * m_sci_d) + 10.0 ** (-0.8 * m_ref_d))
    return np.where(np.isfinite(m_sci), m5, -np.inf)


def depth_model(config: Any) -> "DepthModel":
    """(D1)-(D2) for a telescope: ``C_b = zenith_depth - 1.25 log10(reference_exposure_s / 30 s)`` (section 1).

    A filter without ``reference_depth`` gets a reference far deeper than any
    exposure (99 mag at its zenith seeing): D2 then adds nothing.
    """
    from ..instruments.active import description_of, site_tuple

    if config.telescope == "ztf":  # the calibrated model; ztf.toml's terms equal it (tested)
        return ZTF_DEPTH
    telescope = description_of(config)
    shift = 1.25 * float(np.log10(telescope.depth.reference_exposure_s / 30.0))
    f = telescope.filters
    return DepthModel(
        dark_zenith_depth_30s={b: t.zenith_depth - shift for b, t in f.items()},
        dark_sky_zenith={b: t.sky_zenith for b, t in f.items()},
        extinction={b: t.extinction for b, t in f.items()},
        seeing_airmass_exponent=telescope.depth.seeing_airmass_exponent,
        twilight_slope_mag_per_deg=telescope.depth.twilight_slope_mag_per_deg,
        zenith_fwhm_arcsec={b: t.zenith_fwhm_arcsec for b, t in f.items()},
        reference_depth={b: 99.0 if t.reference_depth is None else t.reference_depth for b, t in f.items()},
        reference_fwhm_arcsec={b: t.zenith_fwhm_arcsec if t.reference_fwhm_arcsec is None
                               else t.reference_fwhm_arcsec for b, t in f.items()},
        sun_minus_v={b: t.sun_minus_v for b, t in f.items()},
        location=site_tuple(telescope))
