"""Frame reconstruction: Poisson solvers (SOR, DCT) over gradient-event Laplacians, brightness-event
baselines (direct integration, Scheerlinck et al.'s high-pass and complementary filters), one tone map."""

from gevsim.reconstruct.brightness import complementary_filter, direct_integration, high_pass_filter
from gevsim.reconstruct.gradient import (
    PAPER_C,
    PAPER_C_SINGLE,
    GradientReconstructor,
    approximate_laplacian,
    global_photodiode_mean,
    quantized_gradients,
    reconstruct,
)
from gevsim.reconstruct.poisson import (
    PAPER_ALPHA,
    PAPER_ITERATIONS,
    SOLVERS,
    dct,
    laplacian,
    solve_poisson,
    sor,
)
from gevsim.tonemap import ToneMap

__all__ = [
    "ToneMap", "complementary_filter", "direct_integration", "high_pass_filter",
    "PAPER_ALPHA", "PAPER_C", "PAPER_C_SINGLE", "PAPER_ITERATIONS", "SOLVERS",
    "GradientReconstructor", "approximate_laplacian", "dct", "global_photodiode_mean",
    "laplacian", "quantized_gradients", "reconstruct", "solve_poisson", "sor",
]
