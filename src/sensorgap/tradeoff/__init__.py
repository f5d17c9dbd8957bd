"""Speed vs accuracy, measured: ``sensorgap tradeoff --out DIR``."""

from sensorgap.tradeoff.measure import run_tradeoff

__all__ = ["run_tradeoff"]
