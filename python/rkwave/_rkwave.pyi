"""Type stubs of the compiled module rkwave._rkwave (re-exported by rkwave)."""

from os import PathLike
from typing import Any, Callable, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

ArrayLike = npt.ArrayLike
FloatArray = npt.NDArray[np.float64]
PathArg = Union[str, PathLike]

class RkwaveError(ValueError):
    """A request rkwave refuses; ``kind`` is the library's error kind (e.g. 'InvalidInput')."""

    kind: str

class ResourceLimitError(MemoryError):
    """Refused before allocating: more memory than the limit."""

class RkwaveWarning(UserWarning):
    """A fallback or warning of a fit (the CLI's ``warning:`` / ``note:`` lines)."""

class Fit:
    """A fitted reconstruction ``f(x) = sum_a c_a Psi_a(x)``."""

    def __call__(self, x: ArrayLike) -> FloatArray: ...
    def evaluate(self, x: ArrayLike) -> FloatArray: ...
    @property
    def coefficients(self) -> FloatArray: ...
    @property
    def indices(self) -> list[int]: ...
    @property
    def levels(self) -> Tuple[int, int]: ...
    @property
    def domain(self) -> Tuple[float, float]: ...
    @property
    def report(self) -> dict[str, Any]: ...
    @property
    def samples(self) -> Optional[FloatArray]: ...

def fit(
    x: ArrayLike,
    y: ArrayLike,
    domain: Optional[Tuple[float, float]] = None,
    p: int = 3,
    levels: Union[Literal["auto"], Tuple[int, int], None] = None,
    method: Literal["single", "local", "global", "dense"] = "single",
    *,
    family: Optional[Literal["db", "sym"]] = None,
    rho: float = 2.0,
    coarse_samples: float = 256.0,
    rings: int = 1,
    solver: Literal["svd", "qr", "cholesky"] = "svd",
    cutoff: float = 1e-12,
    ridge: float = 0.0,
    factorization: Literal["qr", "normal"] = "qr",
) -> Fit: ...
def local_vs_global(
    p: int = 3,
    fine: int = 8,
    coarse: Optional[int] = None,
    samples: int = 1024,
    layout: str = "uniform",
    seed: int = 1,
    signal: str = "smooth",
    rings: int = 1,
    solver: Literal["svd", "qr", "cholesky"] = "svd",
    cutoff: float = 1e-12,
    grid: int = 8192,
    family: Optional[Literal["db", "sym"]] = None,
) -> dict[str, Any]: ...
def reconstruct_image(
    xy: ArrayLike,
    values: ArrayLike,
    resolution: Tuple[int, int],
    p: Optional[int] = None,
    method: str = "wavelet",
    filter: Optional[
        Literal["box", "triangle", "gaussian", "mitchell", "lanczos"]
    ] = None,
    *,
    pixels: Optional[Literal["auto", "fit", "fit-clamped", "box", "shrunk"]] = None,
    rho: Optional[float] = None,
    ridge: Optional[float] = None,
    smoothing: Optional[float] = None,
    drop_nonfinite: bool = False,
) -> Tuple[FloatArray, dict[str, Any]]: ...
def adapt(
    f: Union[Callable[[float], float], str],
    domain: Tuple[float, float] = (0.0, 1.0),
    budget: int = 100_000,
    *,
    p: int = 3,
    tolerance: float = 1e-6,
    max_depth: int = 32,
    base_samples: int = 256,
    seed: int = 1,
    rho: float = 2.0,
    theta: float = 0.5,
    indicator: Literal["coefficients", "residual", "both"] = "coefficients",
    probes: int = 1,
    layout: str = "jittered",
    coarse: Optional[int] = None,
    base_depth: Optional[int] = None,
    family: Optional[Literal["db", "sym"]] = None,
) -> Fit: ...

class Plan:
    """Adaptive sampling of the image plane driven by a renderer, in process."""

    def __init__(
        self,
        resolution: Tuple[int, int],
        spp: Optional[int] = None,
        budget: Optional[int] = None,
        *,
        p: Optional[int] = None,
        rho: Optional[float] = None,
        below_pixel: Optional[int] = None,
        seed: Optional[int] = None,
        false_alarm: Optional[float] = None,
        min_growth: Optional[float] = None,
        pixel_share: Optional[float] = None,
        pattern: Optional[Literal["sobol", "stratified"]] = None,
        spread: Optional[Literal["indicator", "uncertainty", "uniform"]] = None,
        solver: Optional[Literal["pcg", "direct", "schwarz"]] = None,
        output_pixels: Optional[str] = None,
        tile: Optional[int] = None,
        halo: Optional[int] = None,
    ) -> None: ...
    def positions(self) -> FloatArray: ...
    def add(
        self, xy: ArrayLike, values: ArrayLike, *, drop_nonfinite: bool = False
    ) -> None: ...
    @property
    def done(self) -> bool: ...
    @property
    def round(self) -> int: ...
    def image(self, residual: bool = True) -> FloatArray: ...
    @property
    def samples(self) -> Optional[FloatArray]: ...
    @property
    def report(self) -> dict[str, Any]: ...
    def save(self, dir: PathArg, overwrite: bool = False) -> None: ...
    @staticmethod
    def load(
        dir: PathArg,
        samples: Union[ArrayLike, PathArg, None] = None,
        positions: Union[ArrayLike, PathArg, None] = None,
    ) -> "Plan": ...

def set_memory_limit(limit: Union[int, str, None]) -> None: ...

class PartialFits:
    """The single-scale banded QR triangle of a range of consecutive 1D samples."""

    @property
    def samples(self) -> int: ...
    @property
    def levels(self) -> Tuple[int, int]: ...
    def merge(self, later: PartialFits) -> PartialFits: ...
    def finish(self, ridge: float = 0.0) -> Fit: ...
    def __reduce__(self) -> Tuple[Any, ...]: ...

def partial(
    x: ArrayLike,
    y: ArrayLike,
    domain: Tuple[float, float],
    p: int = 3,
    levels: Tuple[int, int] = (4, 8),
    start: int = 0,
    *,
    family: Optional[Literal["db", "sym"]] = None,
) -> PartialFits: ...
def auto_levels(
    samples: int, p: int = 3, *, rho: float = 2.0, coarse_samples: float = 256.0
) -> Tuple[int, int]: ...

class TileGeometry:
    """The tile grid of a ``W x H`` image: tiles of ``tile`` pixels, windows grown by ``halo``."""

    def __init__(self, resolution: Tuple[int, int], tile: int, halo: int = 12) -> None: ...
    @property
    def resolution(self) -> Tuple[int, int]: ...
    @property
    def tile(self) -> int: ...
    @property
    def halo(self) -> int: ...
    @property
    def grid(self) -> Tuple[int, int]: ...
    @property
    def count(self) -> int: ...
    def interior(self, index: int) -> Tuple[int, int, int, int]: ...
    def window(self, index: int) -> Tuple[int, int, int, int]: ...

def fit_tile(
    xy: ArrayLike,
    values: ArrayLike,
    geometry: TileGeometry,
    tile: int,
    total_samples: int,
    p: int = 2,
    *,
    rho: Optional[float] = None,
    ridge: Optional[float] = None,
) -> Tuple[FloatArray, dict[str, Any]]: ...

class PendingRound:
    """A round of ``TiledPlanRounds`` begun and not yet committed."""

class HeldBand:
    """A band's tiles' whole states, held by the worker that steps the band."""

    @property
    def rows(self) -> Tuple[int, int]: ...
    @property
    def digest(self) -> str: ...

class TiledPlanRounds:
    """The client's side of a tiled plan run as band tasks (``rkwave.dask.TiledPlan``)."""

    def __init__(
        self,
        resolution: Tuple[int, int],
        spp: Optional[int] = None,
        budget: Optional[int] = None,
        *,
        tile: int,
        halo: Optional[int] = None,
        p: Optional[int] = None,
        rho: Optional[float] = None,
        below_pixel: Optional[int] = None,
        seed: Optional[int] = None,
        false_alarm: Optional[float] = None,
        min_growth: Optional[float] = None,
        pixel_share: Optional[float] = None,
        pattern: Optional[Literal["sobol", "stratified"]] = None,
        spread: Optional[Literal["indicator", "uncertainty", "uniform"]] = None,
        solver: Optional[Literal["pcg", "direct", "schwarz"]] = None,
        output_pixels: Optional[str] = None,
        rows_per_task: int = 1,
        threads: int = 1,
    ) -> None: ...
    def positions(self) -> FloatArray: ...
    def begin(
        self, xy: ArrayLike, values: ArrayLike
    ) -> Tuple[Optional[PendingRound], list[Tuple[bytes, FloatArray, Tuple[int, int]]]]: ...
    def commit(self, pending: PendingRound, outcomes: list[bytes]) -> None: ...
    def final_tasks(
        self, residual: bool = True
    ) -> list[Tuple[bytes, FloatArray, Tuple[int, int]]]: ...
    def stitch(
        self, strips: list[Tuple[int, int, int, int, FloatArray]]
    ) -> FloatArray: ...
    @property
    def done(self) -> bool: ...
    @property
    def round(self) -> int: ...
    @property
    def channels(self) -> Optional[int]: ...
    @property
    def report(self) -> dict[str, Any]: ...
    @property
    def held_bands(self) -> list[Tuple[int, int]]: ...
    def held_band(self, rows: Tuple[int, int]) -> HeldBand: ...
    def initial_band(self, rows: Tuple[int, int]) -> HeldBand: ...
    def state_json(self, held: list[HeldBand] = ...) -> str: ...

def tiled_plan_band(
    task: bytes, held: HeldBand, samples: FloatArray
) -> Tuple[bytes, HeldBand]: ...
def tiled_plan_final_band(
    task: bytes, held: HeldBand, samples: FloatArray
) -> Tuple[int, int, int, int, FloatArray]: ...
