"""The tail probabilities and quantiles accelrig's checks use, from ``scipy.special``.

``scipy.stats`` builds a hundred distribution objects at import: about 0.7 s of CPU at the start of
every command that reaches a chi-square or F test, far more than a static calibration's whole
analysis (~50 ms).  The checks need only a few functions, which ``scipy.special`` computes with the
same routines (identical values); these objects keep the ``scipy.stats`` spelling at the call sites
(``chi2.sf(x, dof)``, ``f.sf(x, dfn, dfd)``).
"""

from __future__ import annotations

import numpy as np
from scipy import special


class _Chi2:
    @staticmethod
    def sf(x, df):
        """P(X > x) for a chi-square with ``df`` degrees of freedom (1 for x <= 0, as scipy.stats)."""
        return special.chdtrc(df, np.where(np.asarray(x) < 0, 0.0, x))

    @staticmethod
    def isf(q, df):
        """x with P(X > x) = q for a chi-square with ``df`` degrees of freedom."""
        return special.chdtri(df, q)


class _F:
    @staticmethod
    def sf(x, dfn, dfd):
        """P(X > x) for an F distribution with (``dfn``, ``dfd``) degrees of freedom (1 for x <= 0)."""
        return special.fdtrc(dfn, dfd, np.where(np.asarray(x) < 0, 0.0, x))


chi2 = _Chi2()
f = _F()


def normal_cdf(x):
    return special.ndtr(x)


def student_t_quantile(p, dof):
    """The ``p`` quantile of Student's t with ``dof`` degrees of freedom."""
    return special.stdtrit(dof, p)
