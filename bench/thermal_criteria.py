#!/usr/bin/env python3
"""Which thermal model would a time-ordered criterion inside the training part keep?

A study, not a timing (docs/thermal.md, "Real data"): for some models `mtcal thermal fit` lists
on a real data set (static least squares on temperatures, or on temperatures through first-order
lags, as processing/thermal_model.h fits them), their open-loop RMS on the test part (the last
40 % of the rows) and under several criteria that see the training part only: rolling origins
(each fit on the rows before an origin predicts up to the next), the validation block (the
training part's last quarter) and contiguous blocks each left out in turn.

    python3 bench/thermal_criteria.py "Thermal Expansion Error.csv"

The file: a displacement column first, then the temperatures, one row a minute (the data set of
ruoheng-du/thermal-expansion-error-prediction; not part of mtcal: it has no licence).
"""
import sys

import numpy as np

MODELS = {  # name: [(temperature column, first-order lag in minutes; 0: none)]
    "forward selection of 3: T1, T13, T14": [(1, 0), (13, 0), (14, 0)],
    "forward selection of 4: T1, T13, T14, T15": [(1, 0), (13, 0), (14, 0), (15, 0)],
    "every sensor": [(c, 0) for c in range(16)],
    "kept: T5 lag 80 min, T4 lag 160 min": [(5, 80), (4, 160)],
    "T5 lag 80 min": [(5, 80)],
}


def lagged(x, tau_min):
    if tau_min == 0:
        return x
    a = 1.0 - np.exp(-1.0 / tau_min)
    u = np.empty_like(x)
    u[0] = x[0]
    for i in range(1, len(x)):
        u[i] = u[i - 1] + a * (x[i] - u[i - 1])
    return u


def fit(x, y):
    a = np.c_[np.ones(len(y)), x]
    b = np.linalg.lstsq(a, y, rcond=None)[0]
    return lambda xn: np.c_[np.ones(len(xn)), xn] @ b


def rms(e):
    return float(np.sqrt(np.mean(e ** 2)))


def rolling(x, y, n_train, origins):
    """Fits on the rows before each origin predict up to the next one (the last: the training part's end)."""
    err = []
    for k, o in enumerate(origins):
        a = int(o * n_train)
        b = int(origins[k + 1] * n_train) if k + 1 < len(origins) else n_train
        err.append(y[a:b] - fit(x[:a], y[:a])(x[a:b]))
    return rms(np.concatenate(err))


def blocked(x, y, blocks):
    err = []
    for f in range(blocks):
        a, b = f * len(y) // blocks, (f + 1) * len(y) // blocks
        rest = np.r_[0:a, b:len(y)]
        err.append(y[a:b] - fit(x[rest], y[rest])(x[a:b]))
    return rms(np.concatenate(err))


def main(path):
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    y, temperatures = data[:, 0], data[:, 1:]
    n_train = int(0.6 * len(y))
    print("| model | test, open loop | rolling origins 50..90 % | 30..90 % | validation block | 5 blocks |")
    print("|---|---|---|---|---|---|")
    for name, inputs in MODELS.items():
        x = np.column_stack([lagged(temperatures[:, c], tau) for c, tau in inputs])
        test = rms(y[n_train:] - fit(x[:n_train], y[:n_train])(x[n_train:]))
        print(f"| {name} | {test:.3f} | {rolling(x, y, n_train, [.5, .6, .7, .8, .9]):.3f} | "
              f"{rolling(x, y, n_train, [.3, .4, .5, .6, .7, .8, .9]):.3f} | {rolling(x, y, n_train, [.75]):.3f} | "
              f"{blocked(x[:n_train], y[:n_train], 5):.3f} |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
