"""Granular media: the 2D RFT coefficient model alpha(beta, gamma) and its scale zeta.

The 2D model is Li, Zhang & Goldman, Science 339:1408 (2013): the stress on a small plate with
attack angle beta moving along intrusion angle gamma at depth |z| is alpha(beta, gamma) |z|, with

    alpha_z = sum_{m,n} A_mn cos(2 m beta + n gamma) + B_mn sin(2 m beta + n gamma)
    alpha_x = sum_{m,n} C_mn cos(2 m beta + n gamma) + D_mn sin(2 m beta + n gamma)

for m in {-1, 0, 1}, n in {0, 1} (their eq. S4 / Table S2). A medium is stored in *generic form*:
dimensionless coefficients normalised so alpha_z(0, pi/2) = 1 (horizontal plate pushed straight
down), times the scale zeta [N/m^3]; alpha_medium = zeta * alpha_generic (Li 2013's "scaling
factor").
The out-of-plane coefficient of the 3D extension (Treers, Cao & Stuart, RA-L 2021) is, to first
order, alpha_y = alpha_x(0, 0); users may supply their own alpha_y(beta).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from mjrft.core import agarwal
from mjrft.core.law import HORIZONTAL_PLATE_NZ
from mjrft.core.units import N_PER_CM3

#: Force models (``Material.model``): Treers, Cao & Stuart 2021 on Li, Zhang & Goldman 2013
#: (the default), and Agarwal, Goldman & Kamrin 2023 (``mjrft.core.agarwal``).
MODELS = ("treers2021", "agarwal3d")
#: Agarwal's generic vertical coefficient of a horizontal plate pushed straight down: -(sum of
#: C1, C2 and C3), since x1 = x2 = x3 = 1 there (0.87504).
AGARWAL_PLATE_DOWN = -(sum(agarwal.C1) + sum(agarwal.C2) + sum(agarwal.C3))
#: Default intruder-medium friction of the agarwal3d model: large enough never to cap the
#: tangential part (the source's example uses 10).
AGARWAL_MU_SURF = 10.0
#: Bulk densities of dry granular media are 1,000-2,000 kg/m^3 (glass beads ~1,500, packing
#: fraction 0.6 of 2,500); a dynamic term's rho_c above this is almost surely in other units.
RHO_C_MAX = 5000.0
#: No medium is denser than its grains, and no solid is denser than osmium (22,590 kg/m^3): a
#: dynamic term's rho_c above this is refused.
RHO_C_LIMIT = 25000.0
#: The dynamic term's lambda is the share of the grains' momentum flux the body feels, of order
#: 1 (the public implementation sets 1); above this the body would feel many times the momentum
#: it gives the grains, and it is refused.
LAMBDA_MAX = 10.0
#: An intruder-medium friction coefficient above this is refused: real surfaces on grains have
#: mu below 1, and the default 10 is chosen large enough never to cap the tangential part.
MU_SURF_MAX = 100.0

#: The (m, n) harmonics of Li 2013's first-order Fourier fit, in a fixed order.
HARMONICS: tuple[tuple[int, int], ...] = ((-1, 0), (0, 0), (1, 0), (-1, 1), (0, 1), (1, 1))
_LETTERS = "ABCD"

AlphaFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
AlphaYFn = Callable[[np.ndarray], np.ndarray]


def _parse_key(key: str) -> tuple[str, int]:
    """'B-11' -> ('B', index of (m=-1, n=1) in HARMONICS)."""
    letter, rest = key[:1], key[1:]
    valid = "letter A/B/C/D then m in {-1,0,1} then n in {0,1}, e.g. 'A00', 'B-11', 'D10'"
    if letter not in _LETTERS or not rest:
        raise ValueError(f"unknown Fourier coefficient name {key!r}; expected {valid}")
    try:
        m, n = int(rest[:-1]), int(rest[-1])
    except ValueError:
        raise ValueError(f"unknown Fourier coefficient name {key!r}; expected {valid}") from None
    if (m, n) not in HARMONICS:
        raise ValueError(f"unknown Fourier coefficient name {key!r}; expected {valid}")
    return letter, HARMONICS.index((m, n))


@dataclass(frozen=True, eq=False)
class FourierCoefficients:
    """Li 2013 Fourier coefficients of alpha_z (A cos, B sin) and alpha_x (C cos, D sin).

    Each of a, b, c, d is a (6,) array over HARMONICS; units are those of the table
    (dimensionless in generic form).
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray

    @classmethod
    def from_mapping(
        cls, table: Mapping[str, float], *, source: str = "table"
    ) -> FourierCoefficients:
        """Build from names like {'A00': .206, 'B-11': .055}; missing terms are zero."""
        arrs = {letter: np.zeros(len(HARMONICS)) for letter in _LETTERS}
        for key, value in table.items():
            letter, idx = _parse_key(str(key))
            v = float(value)
            if not math.isfinite(v):
                raise ValueError(f"{source}: coefficient {key} = {value!r} is not finite")
            arrs[letter][idx] = v
        return cls(*(arrs[letter] for letter in _LETTERS))

    def as_mapping(self) -> dict[str, float]:
        """Non-zero coefficients by name ('A00', 'B-11', ...)."""
        out = {}
        for letter, arr in zip(_LETTERS, (self.a, self.b, self.c, self.d), strict=True):
            for (m, n), v in zip(HARMONICS, arr, strict=True):
                if v != 0.0:
                    out[f"{letter}{m}{n}"] = float(v)
        return out

    def scaled(self, factor: float) -> FourierCoefficients:
        """All coefficients multiplied by factor."""
        return FourierCoefficients(
            self.a * factor, self.b * factor, self.c * factor, self.d * factor
        )

    def _phases(self, beta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
        mn = np.asarray(HARMONICS, dtype=np.float64)
        return (
            2.0 * mn[:, 0] * np.asarray(beta)[..., None] + mn[:, 1] * np.asarray(gamma)[..., None]
        )

    def alpha_z(self, beta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
        """alpha_z at angles beta, gamma [rad] (broadcast), in the table's units."""
        ph = self._phases(beta, gamma)
        return np.cos(ph) @ self.a + np.sin(ph) @ self.b

    def alpha_x(self, beta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
        """alpha_x at angles beta, gamma [rad] (broadcast), in the table's units."""
        ph = self._phases(beta, gamma)
        return np.cos(ph) @ self.c + np.sin(ph) @ self.d


def combined_coefficients(fourier: FourierCoefficients) -> np.ndarray:
    """(18,) coefficients of alpha_z then alpha_x as sums over the products the kernel forms.

    alpha = K0 + K1 c2 + K2 s2 + K3 cg + K4 sg + K5 c2 cg + K6 s2 sg + K7 c2 sg + K8 s2 cg, with
    c2, s2 = cos, sin(2 beta) and cg, sg = cos, sin(gamma); from the 6 harmonics (m, n) of
    HARMONICS by cos(2 m b + n g) and sin(2 m b + n g) expanded (engine/law.cc).
    """

    def comb(c, s):  # c, s: cosine and sine coefficients over HARMONICS
        return [
            c[1],
            c[0] + c[2],
            s[2] - s[0],
            c[4],
            s[4],
            c[3] + c[5],
            c[3] - c[5],
            s[3] + s[5],
            s[5] - s[3],
        ]

    return np.array(comb(fourier.a, fourier.b) + comb(fourier.c, fourier.d), dtype=np.float64)


#: Li 2013 generic coefficients (dimensionless; alpha_z(0, pi/2) = 1), Science 339:1408, Fig. 2.
LI_GENERIC = FourierCoefficients.from_mapping(
    {
        "A00": 0.206,
        "A10": 0.169,
        "B11": 0.212,
        "B01": 0.358,
        "B-11": 0.055,
        "C11": -0.124,
        "C01": 0.253,
        "C-11": 0.007,
        "D10": 0.088,
    },
    source="Li 2013 generic coefficients",
)

# Grid on which user callables are probed at construction (fail fast, not mid-run).
_PROBE_N = 73


def _probe_grid() -> tuple[np.ndarray, np.ndarray]:
    beta, gamma = np.meshgrid(
        np.linspace(-np.pi, 2.0 * np.pi, _PROBE_N), np.linspace(-np.pi, np.pi, _PROBE_N)
    )
    return beta.ravel(), gamma.ravel()


def _check_callable(
    fn: object, name: str, args: tuple[np.ndarray, ...], where: str = ""
) -> np.ndarray:
    """fn(*args) as float64, checked: the shape of args[0] and finite; ValueError naming name
    (and where, e.g. "on the engine's table") otherwise."""
    if not callable(fn):
        raise ValueError(f"{name} must be callable, got {type(fn).__name__}")
    try:
        out = fn(*args)
    except Exception as exc:
        raise ValueError(
            f"{name} raised {type(exc).__name__}: {exc} when called with numpy arrays of shape "
            f"{args[0].shape}; it must accept arrays (wrap scalar code with numpy.vectorize)"
        ) from exc
    try:
        out = np.asarray(out, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} returned {type(out).__name__}, not numbers{where}") from exc
    if out.shape != args[0].shape:
        raise ValueError(
            f"{name} returned shape {out.shape} for inputs of shape {args[0].shape}{where}; "
            "it must return an array of the same shape as its inputs"
        )
    if not np.all(np.isfinite(out)):
        bad = int(np.flatnonzero(~np.isfinite(out))[0])
        at = ", ".join(f"{a[bad]:.4g}" for a in args)
        raise ValueError(
            f"{name} returned a non-finite value ({out[bad]}) at angle(s) ({at}) rad{where}"
        )
    return out


#: Steps per pi of the engine's table of a medium given by callables (``Material.tabulated``):
#: the grid step is h = pi / n in both angles. The default interpolates Li's generic medium,
#: given as callables, to 1.2e-7 of its largest |alpha| (tests/test_tabulated.py) in 570 kB.
TABLE_N = 64
#: Table resolutions accepted: 8 (8e-4 on Li's medium: it warns) to 256 (4.5e-10; 8.8 MB).
TABLE_N_MIN, TABLE_N_MAX = 8, 256
#: The frame's beta leaves [0, pi] only on nearly horizontal plates (docs/design.md 2.2), by at
#: most asin(sqrt(1 - HORIZONTAL_PLATE_NZ^2)) = 0.0447 rad; the table covers this much beyond.
TABLE_BETA_MARGIN = math.asin(math.sqrt(1.0 - HORIZONTAL_PLATE_NZ**2)) + 0.005
#: A table whose interpolation error at its cells' centres exceeds this fraction of the
#: medium's largest |alpha| draws a MaterialWarning: the callables are not smooth at its step.
TABLE_WARN = 1e-4
#: The layout engine/law.h reads: tag, header length, values per node (alpha_x and alpha_z, each
#: value, h d/dbeta, h d/dgamma, h^2 d2/dbeta dgamma); the header is tag, nb, ng, beta0, gamma0,
#: h, then zeros.
TABLE_TAG, TABLE_HEADER, TABLE_NODE = 3.0, 8, 8
_TABLE_GHOST = 2  # nodes sampled beyond each end for the fourth-order differences


def _difference(f: np.ndarray, axis: int) -> np.ndarray:
    """h df/dx by fourth-order central differences along axis (losing two nodes at each end):
    error h^5 f^(5) / 30."""
    n = f.shape[axis]
    at = lambda k: f.take(range(2 + k, n - 2 + k), axis=axis)  # noqa: E731
    return (at(-2) - 8.0 * at(-1) + 8.0 * at(1) - at(2)) / 12.0


def _hermite(s: float) -> tuple[float, float, float, float]:
    """Cubic Hermite weights at s in [0, 1]: values at 0, 1, slopes (times h) at 0, 1."""
    t = 1.0 - s
    return (1.0 + 2.0 * s) * t * t, (3.0 - 2.0 * s) * s * s, s * t * t, -s * s * t


def tabulate(material: Material, n: int = TABLE_N) -> tuple[np.ndarray, float, str]:
    """The engine's table of a medium's generic alphas (the layout of engine/law.h), its
    interpolation error measured at the centres of its cells over the largest |alpha| on it, and
    the alpha ("alpha_x", "alpha_y" or "alpha_z") with that error.

    alpha_x, alpha_z are sampled on nodes (beta0 + i h, -pi + j h), h = pi / n, beta over
    [0, pi] and TABLE_BETA_MARGIN beyond, gamma over [-pi, pi], alpha_y on the same betas; the
    derivatives by fourth-order differences on two more nodes past each end (the callables are
    evaluated there too: they need not be periodic). The engine interpolates bicubic Hermite:
    error at most h^4 / 384 (max |d4 alpha / d beta4| + max |d4 alpha / d gamma4|) + O(h^5).
    Raises ValueError naming the callable that gives a wrong shape or a non-finite value.
    """
    h = math.pi / n
    kb = math.ceil(TABLE_BETA_MARGIN / h)
    nb, ng = n + 2 * kb + 1, 2 * n + 1
    beta0, gamma0 = -kb * h, -math.pi
    ghost = np.arange(-_TABLE_GHOST, 0)
    betas = beta0 + h * np.concatenate([ghost, np.arange(nb + _TABLE_GHOST)])
    gammas = gamma0 + h * np.concatenate([ghost, np.arange(ng + _TABLE_GHOST)])
    where = f" on the engine's table of {material.name!r} (step pi/{n})"
    ax, ay, az = _alphas(material, betas, gammas, where)
    inner = slice(_TABLE_GHOST, -_TABLE_GHOST)
    nodes = np.empty((nb, ng, TABLE_NODE))
    for k, f in enumerate((ax, az)):
        db = _difference(f, 0)  # (nb, ng + 4)
        nodes[:, :, 4 * k] = f[inner, inner]
        nodes[:, :, 4 * k + 1] = db[:, inner]
        nodes[:, :, 4 * k + 2] = _difference(f, 1)[inner, :]
        nodes[:, :, 4 * k + 3] = _difference(db, 1)
    ay_nodes = np.stack([ay[inner], _difference(ay, 0)], axis=-1)
    header = np.zeros(TABLE_HEADER)
    header[:6] = TABLE_TAG, nb, ng, beta0, gamma0, h
    table = np.concatenate([header, nodes.ravel(), ay_nodes.ravel()])
    if not np.all(np.isfinite(table)):
        raise ValueError(f"{material.name!r}: its alphas overflow{where}")
    return table, *_table_error(material, nodes, ay_nodes, betas[inner], gammas[inner], where)


def _alphas(material: Material, betas, gammas, where: str):
    """Generic alpha_x, alpha_y, alpha_z of material on the grid betas x gammas (alpha_y over
    betas), each callable checked."""
    beta, gamma = (a.ravel() for a in np.meshgrid(betas, gammas, indexing="ij"))
    shape = (len(betas), len(gammas))
    if material.fourier is not None:
        ax, az = material.fourier.alpha_x(beta, gamma), material.fourier.alpha_z(beta, gamma)
    else:
        ax = _check_callable(material.alpha_x_fn, "alpha_x(beta, gamma)", (beta, gamma), where)
        az = _check_callable(material.alpha_z_fn, "alpha_z(beta, gamma)", (beta, gamma), where)
    if material.alpha_y_fn is not None:
        ay = _check_callable(material.alpha_y_fn, "alpha_y(beta)", (np.array(betas),), where)
    else:
        ay = np.full(len(betas), material.alpha_y0)
    return ax.reshape(shape), ay, az.reshape(shape)


def _table_error(
    material: Material, nodes, ay_nodes, betas, gammas, where: str
) -> tuple[float, str]:
    """Largest |interpolated - exact| of the three alphas at the centres of the table's cells
    (where the Hermite error term peaks), over the largest |alpha| on its nodes; and which alpha
    it is."""
    w0, w1, d0, d1 = _hermite(0.5)
    h = betas[1] - betas[0]

    def centre(k):  # interpolated value at the cells' centres of node quantity k..k+3
        v, db, dg, dbg = (nodes[:, :, k + c] for c in range(4))
        # Along gamma to the centres, at every beta node: value and beta slope.
        vg = w0 * v[:, :-1] + d0 * dg[:, :-1] + w1 * v[:, 1:] + d1 * dg[:, 1:]
        sg = w0 * db[:, :-1] + d0 * dbg[:, :-1] + w1 * db[:, 1:] + d1 * dbg[:, 1:]
        return w0 * vg[:-1] + d0 * sg[:-1] + w1 * vg[1:] + d1 * sg[1:]

    ax, ay, az = _alphas(material, betas[:-1] + 0.5 * h, gammas[:-1] + 0.5 * h, where)
    y = ay_nodes
    ay_mid = w0 * y[:-1, 0] + d0 * y[:-1, 1] + w1 * y[1:, 0] + d1 * y[1:, 1]
    scale = max(np.abs(nodes[:, :, [0, 4]]).max(), np.abs(ay_nodes[:, 0]).max())
    errors = {
        "alpha_x": np.abs(centre(0) - ax).max(),
        "alpha_z": np.abs(centre(4) - az).max(),
        "alpha_y": np.abs(ay_mid - ay).max(),
    }
    name = max(errors, key=errors.get)
    return (float(errors[name] / scale) if scale > 0.0 else 0.0), name


class MaterialWarning(UserWarning):
    """A medium that is legal but almost surely not what was meant (a unit slip, a stand-in)."""


#: zeta outside [ZETA_LOW, ZETA_HIGH] N/m^3 draws a warning: granular media lie near 1e4-1e7
#: N/m^3 (0.8 mm glass beads: 3.3e5), and a value below 1e3 is most likely one in N/cm^3. Above
#: ZETA_MAX it is refused: no medium is that stiff, and forces on large bodies would overflow.
ZETA_LOW, ZETA_HIGH, ZETA_MAX = 1e3, 1e9, 1e15
#: Generic-form coefficients are dimensionless and of order 1 (Li's set: 0.007-0.358); a set
#: with a larger magnitude than this is refused as a typo or a unit error.
GENERIC_COEFFICIENT_MAX = 100.0
#: Angle steps of the dissipation check over (beta, gamma) in [-pi, pi]^2 (2 degrees).
DISSIPATION_GRID = 181


def warn_if_unusual_zeta(z: float, where: str = "zeta") -> None:
    """Warn (MaterialWarning) if z [N/m^3] is far outside the range of granular media; raise
    ValueError above ZETA_MAX."""
    if not z <= ZETA_MAX:
        raise ValueError(
            f"{where} = {z:g} N/m^3 is above {ZETA_MAX:g} N/m^3: no granular medium is that "
            "stiff (1e4-1e7 N/m^3); check the numbers and their unit"
        )
    if z < ZETA_LOW:
        warnings.warn(
            f"{where} = {z:g} N/m^3 is below {ZETA_LOW:g} N/m^3, tiny for a granular medium "
            f"(0.8 mm glass beads: 3.3e5 N/m^3): was it given in N/cm^3? In N/m^3 that is "
            f"{z * N_PER_CM3:g} (mjrft.N_PER_CM3 = 1e6)",
            MaterialWarning,
            stacklevel=3,
        )
    elif z > ZETA_HIGH:
        warnings.warn(
            f"{where} = {z:g} N/m^3 is above {ZETA_HIGH:g} N/m^3, stiffer than any granular "
            "medium (1e4-1e7 N/m^3); check its unit",
            MaterialWarning,
            stacklevel=3,
        )


def dissipation_violation(material: Material) -> tuple[float, float, float] | None:
    """(work, beta, gamma) at the worst angles [rad] where the medium would push a leading plate
    along its motion (positive work), or None if it dissipates on the whole angle grid.

    From the element law (docs/design.md 2.8) with the frame of 2.2: a plate's normal is
    n = sin(b) e2 - cos(b) z, so it leads iff sin(b + g) > 0, and
    F . v^ = -zeta d dA [f1 alpha_y |v^ . e1| + f23 |v23| (alpha_z sin g + alpha_x cos g)].
    The medium dissipates iff alpha_y >= 0 and alpha_z sin g + alpha_x cos g >= 0 wherever a
    plate leads; work is the most negative value of the latter (generic form), or alpha_y.
    """
    grid = np.linspace(-np.pi, np.pi, DISSIPATION_GRID)
    beta, gamma = np.meshgrid(grid, grid, indexing="ij")
    ax, ay, az = material.alpha_generic(beta, gamma)
    push = np.where(np.sin(beta + gamma) > 1e-9, az * np.sin(gamma) + ax * np.cos(gamma), 0.0)
    k = int(np.argmin(push))
    if push.flat[k] < 0.0:
        return float(push.flat[k]), float(beta.flat[k]), float(gamma.flat[k])
    k = int(np.argmin(ay))
    if ay.flat[k] < 0.0:
        return float(ay.flat[k]), float(beta.flat[k]), 0.0
    return None


def describe_violation(violation: tuple[float, float, float]) -> str:
    """The angles of a dissipation violation, for messages."""
    work, beta, gamma = violation
    return (
        f"it would push a leading plate along its motion at beta = {math.degrees(beta):.0f} deg, "
        f"gamma = {math.degrees(gamma):.0f} deg (alpha_z sin(gamma) + alpha_x cos(gamma) or "
        f"alpha_y = {work:.3g} < 0); RFT media only resist motion (docs/design.md 2.9)"
    )


def _check_zeta(zeta: object, unit: str = "N/m^3") -> float:
    try:
        z = float(zeta)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"zeta must be a finite number > 0 in {unit}, got {zeta!r}") from None
    if not (math.isfinite(z) and z > 0.0):
        raise ValueError(f"zeta must be a finite number > 0 in {unit}, got {zeta!r}")
    return z


@dataclass(frozen=True, eq=False)
class Material:
    """A dry granular medium for RFT: generic-form coefficients times zeta.

    Build with the constructors (``generic``, ``preset``, ``from_table``, ``from_callables``).

    Attributes:
      name: human-readable label.
      zeta: scale factor [N/m^3]; alpha_medium = zeta * alpha_generic.
      fourier: generic-form Fourier coefficients, or None when the model is given by callables.
      alpha_x_fn, alpha_z_fn: generic-form callables (beta, gamma) -> alpha, or None.
      alpha_y_fn: generic-form callable beta -> alpha_y, or None for the constant ``alpha_y0``.
      alpha_y0: constant generic out-of-plane coefficient used when alpha_y_fn is None.
      source: where the numbers come from.
      agarwal: the parameters of Agarwal et al.'s 3D-RFT (``mjrft.core.agarwal.parameters``)
        when that is the force model (``model``, ``with_model``), else None.
      dynamic: lambda rho_c [kg/m^3] of the dynamic (inertial) RFT term, 0 when it is off (the
        default; ``with_dynamic``, docs/models.md "Dynamic RFT").
      table_n: steps per pi of the engine's table of a medium given by callables (``tabulated``).
    """

    name: str
    zeta: float
    fourier: FourierCoefficients | None = None
    alpha_x_fn: AlphaFn | None = field(default=None, repr=False)
    alpha_z_fn: AlphaFn | None = field(default=None, repr=False)
    alpha_y_fn: AlphaYFn | None = field(default=None, repr=False)
    alpha_y0: float = 0.0
    source: str = ""
    agarwal: np.ndarray | None = field(default=None, repr=False)
    dynamic: float = 0.0
    table_n: int = field(default=TABLE_N, repr=False)

    # ----------------------------------------------------------------- constructors
    @classmethod
    def generic(
        cls, zeta: float | None = None, *, zeta_n_per_cm3: float | None = None, name: str = ""
    ) -> Material:
        """Li 2013 generic coefficients scaled by zeta.

        Args:
          zeta: scale [N/m^3] (SI). Give exactly one of zeta and zeta_n_per_cm3.
          zeta_n_per_cm3: the same scale in N/cm^3, the unit of published tables.
        """
        if (zeta is None) == (zeta_n_per_cm3 is None):
            raise ValueError("give exactly one of zeta [N/m^3] and zeta_n_per_cm3 [N/cm^3]")
        if zeta is None:
            z = _check_zeta(zeta_n_per_cm3, "N/cm^3") * N_PER_CM3
        else:
            z = _check_zeta(zeta)
        warn_if_unusual_zeta(z)
        return cls._from_fourier(
            LI_GENERIC, z, name or f"generic (zeta={z / N_PER_CM3:g} N/cm^3)", "Li 2013 generic"
        )

    @classmethod
    def preset(cls, name: str) -> Material:
        """A named medium; see ``PRESETS`` for the names and their sources."""
        try:
            make = PRESETS[name]
        except (KeyError, TypeError):
            raise ValueError(
                f"unknown material preset {name!r}; valid names: {', '.join(sorted(PRESETS))}"
            ) from None
        return make()

    @classmethod
    def from_table(
        cls,
        table: Mapping[str, float],
        *,
        unit: float = N_PER_CM3,
        name: str = "custom table",
        strict: bool = True,
    ) -> Material:
        """A medium from its full (dimensional) Fourier coefficient table.

        Args:
          table: coefficients by name ('A00', 'A10', 'B11', 'B-11', 'C01', 'D10', ...), in `unit`.
          unit: the table's unit in N/m^3 (default N/cm^3, as Li 2013 publishes).
          strict: False turns the refusal of a medium that would not resist every motion into a
            MaterialWarning (for stand-in sets, e.g. tests of the kernel's algebra).
        The table is stored in generic form: zeta = alpha_z(0, pi/2) of the table, in N/m^3.
        Raises ValueError if the medium would not resist every motion (dissipation_violation)
        or its coefficients are out of proportion (GENERIC_COEFFICIENT_MAX).
        """
        u = _check_zeta(unit, "N/m^3 per table unit")
        coeffs = FourierCoefficients.from_mapping(table, source=name)
        az_ref = float(coeffs.alpha_z(0.0, np.pi / 2))
        if not az_ref > 0.0:
            raise ValueError(
                f"{name}: alpha_z(beta=0, gamma=pi/2) = {az_ref:g} must be > 0 "
                "(a horizontal plate pushed down must be resisted)"
            )
        material = cls._from_fourier(coeffs.scaled(1.0 / az_ref), az_ref * u, name, name)
        material.check(name, strict)
        warn_if_unusual_zeta(material.zeta, f"{name}: zeta = alpha_z(0, pi/2) x unit")
        return material

    def check(self, where: str, strict: bool = True) -> None:
        """Raise ValueError, naming ``where``, if this Fourier-form medium's generic coefficients
        are out of proportion or it would not resist every motion of a leading plate (the
        latter only warns, MaterialWarning, if not strict)."""
        values = np.concatenate([self.fourier.a, self.fourier.b, self.fourier.c, self.fourier.d])
        worst = float(np.abs(values).max())
        if not worst <= GENERIC_COEFFICIENT_MAX:
            raise ValueError(
                f"{where}: a generic-form coefficient has magnitude {worst:.3g}, above "
                f"{GENERIC_COEFFICIENT_MAX:g}; generic coefficients are dimensionless and of order "
                "1 (Li's set: 0.007-0.358): check the numbers and their unit"
            )
        violation = dissipation_violation(self)
        if violation is None:
            return
        message = f"{where}: not a dissipative medium: {describe_violation(violation)}"
        if strict:
            raise ValueError(message)
        warnings.warn(message, MaterialWarning, stacklevel=3)

    @classmethod
    def from_callables(
        cls,
        alpha_x: AlphaFn,
        alpha_z: AlphaFn,
        zeta: float,
        alpha_y: AlphaYFn | None = None,
        *,
        name: str = "custom callables",
    ) -> Material:
        """A medium from user 2D model functions in generic (dimensionless) form, times zeta.

        Args:
          alpha_x, alpha_z: vectorized callables (beta, gamma) -> array of the same shape; angles
            in rad, beta the plate attack angle, gamma the intrusion angle (Li 2013 conventions).
          zeta: scale [N/m^3].
          alpha_y: optional vectorized callable beta -> out-of-plane coefficient; default is the
            constant alpha_x(0, 0) (first-order 3D RFT, Treers et al. 2021).
        The callables are probed on a grid of angles now, so shape errors and non-finite values
        are reported at construction rather than mid-simulation; a model that would push a
        leading plate along its motion somewhere draws a MaterialWarning.

        The RFT-only API (``element_forces``, body wrenches) evaluates the callables exactly, in
        NumPy. The engine (MuJoCo's step runs no Python) evaluates them from a table sampled
        once, when a model is loaded (``kernel_coefficients``, ``tabulated``).
        """
        z = _check_zeta(zeta)
        warn_if_unusual_zeta(z)
        beta, gamma = _probe_grid()
        _check_callable(alpha_x, "alpha_x(beta, gamma)", (beta, gamma))
        _check_callable(alpha_z, "alpha_z(beta, gamma)", (beta, gamma))
        if alpha_y is not None:
            _check_callable(alpha_y, "alpha_y(beta)", (beta,))
            ay0 = 0.0
        else:
            ay0 = float(np.asarray(alpha_x(np.zeros(1), np.zeros(1)), dtype=np.float64)[0])
        material = cls(
            name=name,
            zeta=z,
            alpha_x_fn=alpha_x,
            alpha_z_fn=alpha_z,
            alpha_y_fn=alpha_y,
            alpha_y0=ay0,
            source="user callables",
        )
        violation = dissipation_violation(material)
        if violation is not None:  # callables may be stand-ins on purpose: warn, do not refuse
            warnings.warn(
                f"{name}: not a dissipative medium: {describe_violation(violation)}",
                MaterialWarning,
                stacklevel=2,
            )
        return material

    def tabulated(self, n: int = TABLE_N) -> Material:
        """This medium given by callables, with the engine's table of them at step pi / n [rad]
        in both angles (default TABLE_N; TABLE_N_MIN..TABLE_N_MAX).

        The engine tabulates a medium given by callables by itself, at TABLE_N, when a model
        is loaded (``kernel_coefficients``): a scene's medium reaches the engine only as
        coefficients, and every such medium needs a table, so asking for one would only turn
        a working script into an error. Call this for another resolution: the error falls as
        h^4 (``table_error``; 1.2e-7 of the largest |alpha| for Li's generic medium at 64,
        about 16 n^2 doubles of memory). The callables are sampled, and checked, now.
        """
        if self.compiled or self.agarwal is not None:
            raise ValueError(
                f"material {self.name!r} is given by coefficients: the engine evaluates it "
                "exactly; only media given by callables are tabulated"
            )
        if not (isinstance(n, int | np.integer) and TABLE_N_MIN <= n <= TABLE_N_MAX):
            raise ValueError(
                f"tabulated(n={n!r}): expected an integer number of steps per pi in "
                f"{TABLE_N_MIN}..{TABLE_N_MAX}"
            )
        material = dataclasses.replace(self, table_n=int(n))
        material.kernel_coefficients  # noqa: B018 (samples and checks the callables now)
        return material

    @functools.cached_property
    def _table(self) -> tuple[np.ndarray, float, str]:
        """``tabulate(self, self.table_n)``, once; warns (MaterialWarning) if its error is above
        TABLE_WARN."""
        table, error, worst = tabulate(self, self.table_n)
        if error > TABLE_WARN:
            warnings.warn(
                f"{self.name}: the engine's table (step pi/{self.table_n}) misses {worst} by "
                f"{error:.2g} of the medium's largest |alpha| at its cells' centres: the "
                "callables are not smooth at that step; give a finer table (Material."
                "tabulated(n=...)) or smoother callables",
                MaterialWarning,
                stacklevel=3,
            )
        return table, error, worst

    @property
    def table_error(self) -> float:
        """The engine's table's interpolation error for a medium given by callables: the largest
        |table - callable| of alpha_x, alpha_z and alpha_y at the centres of its cells, over
        the largest |alpha| on its nodes (0 for media given by coefficients)."""
        return 0.0 if self.compiled or self.agarwal is not None else self._table[1]

    @classmethod
    def _from_fourier(cls, coeffs: FourierCoefficients, zeta: float, name: str, source: str):
        return cls(
            name=name,
            zeta=zeta,
            fourier=coeffs,
            alpha_y0=float(coeffs.alpha_x(0.0, 0.0)),
            source=source,
        )

    def with_model(self, model: str, *, mu_surf: float = AGARWAL_MU_SURF) -> Material:
        """This medium under force model ``model`` (``MODELS``): itself for "treers2021"; for
        "agarwal3d", Agarwal et al.'s 3D-RFT with its scale xi_n matched to this medium's at the
        motion every table is normalised by, a horizontal plate pushed straight down
        (xi_n = alpha_z(0, pi/2) / AGARWAL_PLATE_DOWN), and intruder-medium friction mu_surf."""
        if model not in MODELS:
            raise ValueError(f"unknown force model {model!r}; valid: {', '.join(MODELS)}")
        if self.dynamic > 0.0:  # the dynamic term goes with the medium, whatever the model
            return dataclasses.replace(
                dataclasses.replace(self, dynamic=0.0).with_model(model, mu_surf=mu_surf),
                dynamic=self.dynamic,
            )
        if model == "treers2021":
            if self.agarwal is not None:
                raise ValueError(
                    f"material {self.name!r} is an agarwal3d medium: build the treers2021 one "
                    "from its preset, zeta or table"
                )
            return self
        if self.agarwal is not None:  # already agarwal3d: a new surface friction
            return Material.agarwal3d(self.agarwal[agarwal.XI_N], mu_surf, name=self.name,
                                      source=self.source)  # fmt: skip
        if self.fourier is None:
            raise ValueError(
                f"material {self.name!r} is given by callables: the agarwal3d model needs its "
                "scale, alpha_z of a plate pushed straight down; give a preset, zeta or a table"
            )
        plate_down = float(self.fourier.alpha_z(np.array(0.0), np.array(math.pi / 2)))
        return Material.agarwal3d(self.zeta * plate_down / AGARWAL_PLATE_DOWN, mu_surf,
                                  name=f"{self.name} (agarwal3d)",
                                  source=f"{self.source}; scale matched for agarwal3d")  # fmt: skip

    def with_dynamic(self, rho_c: float, lam: float = 1.0) -> Material:
        """This medium with the dynamic RFT inertial term: a leading element of acting area A
        [m^2] moving at v [m/s] feels -lam rho_c (n . v)^2 A n more (n its outward normal),
        the momentum flux of the grains it sets moving; rho_c [kg/m^3] the medium's bulk
        density, lam (dimensionless) the fraction of that flux the body feels. rho_c = 0
        switches it off."""
        for label, value in (("rho_c", rho_c), ("lambda", lam)):
            try:
                ok = math.isfinite(float(value)) and float(value) >= 0.0
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ValueError(
                    f"dynamic RFT {label} = {value!r}: expected a finite number >= 0"
                    + (" in kg/m^3 (bulk density)" if label == "rho_c" else "")
                )
        rho_c, lam = float(rho_c), float(lam)
        if rho_c > RHO_C_LIMIT:
            raise ValueError(
                f"dynamic RFT rho_c = {rho_c:g} kg/m^3: expected 0 to {RHO_C_LIMIT:g} kg/m^3, the "
                "medium's bulk density (no medium is denser than its grains, no solid denser than "
                "osmium's 22,590; dry sands and glass beads: 1,000-2,000)"
            )
        if lam > LAMBDA_MAX:
            raise ValueError(
                f"dynamic RFT lambda = {lam:g}: expected 0 to {LAMBDA_MAX:g}, the share of the "
                "grains' momentum flux the body feels (of order 1; the public implementation "
                "sets 1)"
            )
        if rho_c * lam > 0.0 and not self.compiled:
            raise ValueError(
                f"material {self.name!r} is given by callables: the dynamic RFT term runs in the "
                "compiled kernel only; give a preset, zeta or a table"
            )
        if rho_c > RHO_C_MAX:
            warnings.warn(
                f"dynamic RFT rho_c = {rho_c:g} kg/m^3 is denser than any granular medium "
                f"(> {RHO_C_MAX:g}); is it in kg/m^3?", MaterialWarning, stacklevel=2)  # fmt: skip
        return dataclasses.replace(self, dynamic=float(rho_c * lam))

    @classmethod
    def agarwal3d(
        cls, xi_n: float, mu_surf: float = AGARWAL_MU_SURF, *, name: str = "", source: str = ""
    ) -> Material:
        """Agarwal et al.'s 3D-RFT (``mjrft.core.agarwal``) with scale xi_n [N/m^3] (from bulk
        density and internal friction: ``agarwal.xi_n``) and intruder-medium friction."""
        xi = _check_zeta(xi_n)
        if not (math.isfinite(mu_surf) and 0.0 <= mu_surf <= MU_SURF_MAX):
            raise ValueError(
                f"mu_surf = {mu_surf!r}: expected a friction coefficient from 0 to "
                f"{MU_SURF_MAX:g} (real surfaces on grains: below 1; the default "
                f"{AGARWAL_MU_SURF:g} is chosen never to cap the tangential part)"
            )
        return cls(name or f"agarwal3d (xi_n={xi / N_PER_CM3:g} N/cm^3)",
                   xi * AGARWAL_PLATE_DOWN, source=source or "Agarwal, Goldman & Kamrin 2023",
                   agarwal=agarwal.parameters(xi, mu_surf))  # fmt: skip

    @property
    def model(self) -> str:
        """The force model: "treers2021" (Treers et al. 2021 on Li 2013) or "agarwal3d"."""
        return "agarwal3d" if self.agarwal is not None else "treers2021"

    @property
    def compiled(self) -> bool:
        """True if the compiled kernel evaluates this medium exactly, from its coefficients
        (Fourier form, constant alpha_y, or the agarwal3d model). A medium given by callables
        is not: the RFT-only API evaluates it in NumPy, the engine from its table."""
        return (self.fourier is not None or self.agarwal is not None) and self.alpha_y_fn is None

    @functools.cached_property
    def kernel_coefficients(self) -> np.ndarray:
        """The engine's coefficients: (18,) generic coefficients in its combined form (Fourier
        media), (agarwal.SIZE,) parameters of the agarwal3d model, or, for a medium given by
        callables, the table of its alphas at step pi / table_n (``tabulate``; sampled here,
        once); with the dynamic term, its lambda rho_c [kg/m^3] appended."""
        if self.agarwal is not None:
            base = self.agarwal
        elif not self.compiled:
            base = self._table[0]
        else:
            base = combined_coefficients(self.fourier)
        # The kernel reads a dynamic term's coefficient from one extra entry (kernel.N_COMBINED).
        return np.append(base, self.dynamic) if self.dynamic > 0.0 else base

    # ----------------------------------------------------------------- evaluation
    def alpha_generic(
        self, beta: np.ndarray, gamma: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Generic-form (alpha_x, alpha_y, alpha_z) at angles beta, gamma [rad] (broadcast)."""
        beta, gamma = np.broadcast_arrays(
            np.asarray(beta, dtype=np.float64), np.asarray(gamma, dtype=np.float64)
        )
        if self.fourier is not None:
            ax, az = self.fourier.alpha_x(beta, gamma), self.fourier.alpha_z(beta, gamma)
        else:
            ax = np.asarray(self.alpha_x_fn(beta, gamma), dtype=np.float64)
            az = np.asarray(self.alpha_z_fn(beta, gamma), dtype=np.float64)
        if self.alpha_y_fn is not None:
            ay = np.asarray(self.alpha_y_fn(beta), dtype=np.float64)
        else:
            ay = np.full(beta.shape, self.alpha_y0)
        return ax, ay, az

    def alpha(
        self, beta: np.ndarray, gamma: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Dimensional (alpha_x, alpha_y, alpha_z) [N/m^3] at angles beta, gamma [rad]."""
        ax, ay, az = self.alpha_generic(beta, gamma)
        return self.zeta * ax, self.zeta * ay, self.zeta * az


def _glass_beads() -> Material:
    # Treers, Cao & Stuart (RA-L 2021): 0.8 mm glass beads, zeta = 0.33 N/cm^3, Li's generic set.
    return Material.generic(zeta_n_per_cm3=0.33, name="glass_beads")


# Li, Zhang & Goldman, Science 339:1408 (2013), supplementary Table S2: the leading first-order
# Fourier terms of alpha_z (A, B) and alpha_x (C, D) for poppy seeds, in N/cm^3, loosely packed
# (LP) and closely packed (CP). Values as transcribed in public RFT codes (e.g. the Isaac Lab soft
# contact models); Li's generic set is the average of such tables normalised to alpha_z(0, pi/2).
POPPY_SEEDS_LP_N_PER_CM3 = {
    "A00": 0.051, "A10": 0.047, "B11": 0.053, "B01": 0.083, "B-11": 0.020,
    "C11": -0.026, "C01": 0.057, "C-11": 0.0, "D10": 0.025,
}  # fmt: skip
POPPY_SEEDS_CP_N_PER_CM3 = {
    "A00": 0.094, "A10": 0.092, "B11": 0.092, "B01": 0.151, "B-11": 0.035,
    "C11": -0.039, "C01": 0.086, "C-11": 0.018, "D10": 0.046,
}  # fmt: skip


def _poppy_lp() -> Material:
    return Material.from_table(POPPY_SEEDS_LP_N_PER_CM3, name="poppy_seeds_lp")


def _poppy_cp() -> Material:
    return Material.from_table(POPPY_SEEDS_CP_N_PER_CM3, name="poppy_seeds_cp")


def _li_generic_unit() -> Material:
    return Material.generic(zeta_n_per_cm3=1.0, name="generic_1ncm3")


#: Named media for ``Material.preset``: name -> constructor.
PRESETS: Mapping[str, Callable[[], Material]] = MappingProxyType(
    {
        "glass_beads": _glass_beads,
        "poppy_seeds_lp": _poppy_lp,
        "poppy_seeds_cp": _poppy_cp,
        "generic_1ncm3": _li_generic_unit,
    }
)


def as_material(value: Material | str, argument: str = "material") -> Material:
    """`value` as a Material: a Material itself, or a preset's name (``Material.preset``, as
    ``GranularField`` and the environments take it). Raises ValueError for an unknown name and
    TypeError for anything else, each naming `argument` and the presets."""
    if isinstance(value, Material):
        return value
    if isinstance(value, str):
        try:
            return Material.preset(value)
        except ValueError as exc:
            raise ValueError(f"{argument}={value!r}: {exc}") from None
    raise TypeError(
        f"{argument} must be a mjrft.Material or a preset name ({', '.join(sorted(PRESETS))}), "
        f"got {type(value).__name__}"
    )
