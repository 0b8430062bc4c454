"""Regenerate tests/golden/trend_scipy.json: fixed series and SciPy's answers.

    python3 tests/python/trend_golden.py tests/golden/trend_scipy.json   (needs numpy, scipy)

x is the AE number 1..n, as in `aepipe trend`; y are power-ratio-like series with trends of
every strength (p from ~1 down to ~1e-250), short series (n = 3, 4) and a negative trend.
Every float is written with repr (17 significant digits). The integration test
`trend_statistics_agree_with_scipy` checks aepipe's statistics against these to 1e-9.
"""
import json
import sys

import numpy as np
import scipy
from scipy import stats

rng = np.random.default_rng(20261122)
cases = []
for n, slope, noise in [(651, 7.68e-4, 0.1), (651, -8.3e-4, 0.1), (651, 1e-5, 0.05), (651, 2e-3, 0.01),
                        (651, 0.0, 0.1), (120, 3e-4, 0.02), (25, -0.01, 0.05), (10, 0.02, 0.05),
                        (4, 0.1, 0.05), (3, 0.3, 0.1), (651, 5e-3, 1e-4)]:
    x = np.arange(1, n + 1, dtype=float)
    y = 0.2 + slope * x + noise * rng.standard_normal(n)
    lr = stats.linregress(x, y)
    pr = stats.pearsonr(x, y)
    cases.append(dict(n=n, x=[repr(float(v)) for v in x], y=[repr(float(v)) for v in y],
                      slope=repr(float(lr.slope)), intercept=repr(float(lr.intercept)),
                      r=repr(float(lr.rvalue)), p_linregress=repr(float(lr.pvalue)),
                      p_pearsonr=repr(float(pr.pvalue)), stderr=repr(float(lr.stderr))))
json.dump(dict(scipy=scipy.__version__, numpy=np.__version__, cases=cases), open(sys.argv[1], "w"), indent=0)
print(f"{len(cases)} cases -> {sys.argv[1]} (scipy {scipy.__version__})")
