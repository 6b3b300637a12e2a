"""Numerical building blocks, apart from the harness: the robust Pade approximant (``pade``,
used by Borel-Pade-Laplace) and the Taylor-series arithmetic of the problems' recurrences
(``series``: products, powers, exponentials of truncated series, Horner's rule)."""
