#!/usr/bin/env python3
"""Reference outputs of scipy's 4th-order Butterworth low-pass for railgrip's filter tests.

Run from the repository root:  python3 tests/data/signal/make_reference.py
Needs numpy and scipy (pip install numpy scipy). Writes tests/data/signal/<case>.csv with the
columns  x, causal_<fc>, zero_phase_<fc>  for fc in CUTOFFS, every value as %.17g, and prints
the versions used and scipy's time for sosfiltfilt on one hour at 417 Hz (the figure README
quotes next to railgrip's benchmark).

  causal_<fc>     = sosfilt(sos, x, zi=sosfilt_zi(sos) * x[0])    (steady state at the first sample)
  zero_phase_<fc> = sosfiltfilt(sos, x)                            (odd padding, 3 * 5 samples)
  sos             = butter(4, fc, fs=FS, output='sos')
"""
import pathlib
import time

import numpy as np
import scipy
from scipy import signal

FS = 417.0
CUTOFFS = (1.5, 4.0)
HERE = pathlib.Path(__file__).resolve().parent


def cases():
    rng = np.random.default_rng(20261121)
    n = 2085  # 5 s
    t = np.arange(n) / FS
    # A step from 0 to 1 at 1 s.
    step = np.where(t >= 1.0, 1.0, 0.0)
    # A linear chirp 0.1 -> 20 Hz around an offset of 10.
    f0, f1 = 0.1, 20.0
    chirp = 10.0 + np.sin(2 * np.pi * (f0 * t + 0.5 * (f1 - f0) / t[-1] * t * t))
    # A noisy radar trace: 33.3 m/s braking at 0.8 m/s^2 with a slow wobble, white noise of
    # 0.05 m/s and a few single-sample spikes of about 3 m/s.
    radar = 33.3 - 0.8 * t + 0.05 * np.sin(2 * np.pi * 0.7 * t) + 0.05 * rng.standard_normal(n)
    spikes = rng.choice(n, size=6, replace=False)
    radar[spikes] += 3.0 * rng.choice([-1.0, 1.0], size=6)
    # Shortest signal sosfiltfilt accepts (padlen 15): 16 samples.
    short = np.linspace(1.0, 2.0, 16) ** 2
    return {"step": step, "chirp": chirp, "radar": radar, "short": short}


def main():
    print(f"numpy {np.__version__}, scipy {scipy.__version__}")
    for name, x in cases().items():
        cols = {"x": x}
        for fc in CUTOFFS:
            sos = signal.butter(4, fc, fs=FS, output="sos")
            zi = signal.sosfilt_zi(sos) * x[0]
            cols[f"causal_{fc:g}"] = signal.sosfilt(sos, x, zi=zi)[0]
            cols[f"zero_phase_{fc:g}"] = signal.sosfiltfilt(sos, x)
        path = HERE / f"{name}.csv"
        with open(path, "w") as f:
            f.write(",".join(cols) + "\n")
            for row in zip(*cols.values()):
                f.write(",".join("%.17g" % v for v in row) + "\n")
        print(f"wrote {path.relative_to(HERE.parents[2])} ({len(x)} samples)")

    # scipy's time for the zero-phase filter on one hour at 417 Hz, 9 channels.
    n = int(3600 * FS)
    x = np.cumsum(np.random.default_rng(1).standard_normal(n)) * 1e-3 + 30.0
    sos = signal.butter(4, 4.0, fs=FS, output="sos")
    best = min(_timed(lambda: signal.sosfiltfilt(sos, x)) for _ in range(5))
    print(f"scipy sosfiltfilt, 1 h at 417 Hz ({n} samples): {best * 1e3:.1f} ms per channel, "
          f"{9 * best * 1e3:.0f} ms for 9 channels")


def _timed(f):
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
