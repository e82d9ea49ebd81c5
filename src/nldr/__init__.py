"""nldr: the non-linear dimensionality regularizer of Garg, Eriksson and Reid (2016)."""

__version__ = "0.1.0"
