"""Evaluation: reconstruct frames from an emulation file, score them against its ground
truth and write the results (the solvers and filters themselves live in
:mod:`gevsim.reconstruct`)."""

from gevsim.evaluation.methods import METHODS, Method, check_method
from gevsim.evaluation.output import side_by_side, write_reconstructions
from gevsim.evaluation.runner import Reconstruction, ground_truth, reconstruct_file

__all__ = ["METHODS", "Method", "Reconstruction", "check_method", "ground_truth", "reconstruct_file", "side_by_side",
           "write_reconstructions"]
