#!/usr/bin/env python3
"""What calling a model through its FMU costs, against the bare C header, in one run.

    scripts/fmu-overhead.py [MODEL] [--bin target/release/railgrip] [--steps 20000]

Exports MODEL (default: the bundled golden 2-input network) with `railgrip export --fmu`, then
times on this machine, one after the other:
  1. the bare C header (sources/model.h of the FMU): ns per mu_vt call over 1 024 inputs,
     built portably (-O2, -ffp-contract=off, exact FMA through C99 fma() calls), cloned for
     CPUs with FMA as the FMU's binary is, and as a native build would be (-O2 -march=native);
  2. a C harness that loads the FMU's binary (dlopen) and per co-simulation step calls
     fmi2SetReal (every input), fmi2DoStep and fmi2GetReal (mu): ns per step; and the same
     without fmi2DoStep (what a Model Exchange importer pays per evaluation);
  3. FMPy: simulate_fmu in co-simulation over --steps steps with input signals, and FMPy's
     FMU2Slave driven step by step from Python (setReal, doStep, getReal): µs per step.
Prints one line per figure and the CPU. Needs cc, python3 with numpy and fmpy.
"""

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

HARNESS = r"""
#define _POSIX_C_SOURCE 199309L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "model.h"

typedef void *(*inst_t)(const char *, int, const char *, const char *, const void *, int, int);
typedef int (*setup_t)(void *, int, double, double, int, double);
typedef int (*mode_t_)(void *);
typedef int (*real_t)(void *, const unsigned int *, size_t, double *);
typedef int (*step_t)(void *, double, double, int);
typedef void (*free_t)(void *);
typedef struct {
    void (*logger)(void *, const char *, int, const char *, const char *, ...);
    void *(*allocate)(size_t, size_t);
    void (*free)(void *);
    void (*step_finished)(void *, int);
    void *env;
} callbacks;

/* The bare header as the FMU's binary builds it: the evaluation cloned for CPUs with FMA. */
#if defined(__x86_64__) && defined(__GLIBC__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("fma", "default"), flatten))
#endif
static double cloned(double dv, double ddv, double v, double t) {
    return railgrip_model_mu_vt(dv, ddv, v, t);
}

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1e9 + t.tv_nsec;
}

int main(int argc, char **argv) {
    enum { N = 1024, ROUNDS = 200, REPEATS = 15 };
    static double dv[N], ddv[N], v[N];
    double s = 0.0, best_bare = 1e30, best_cloned = 1e30, best_step = 1e30, best_set_get = 1e30;
    int i, r, k, n_in = 0, arg[4];
    /* argv[3]: which evaluator argument (0 slip, 1 slip rate, 2 speed, 3 temperature) each of
       the FMU's inputs is, e.g. "0,2,3" for a Polach model with a temperature law */
    for (const char *p = argv[3]; *p && n_in < 4; p++)
        if (*p >= '0' && *p <= '3') arg[n_in++] = *p - '0';
    for (i = 0; i < N; ++i) {
        dv[i] = 0.004 * i; ddv[i] = ((i * 7919) % 1000) / 100.0 - 5.0; v[i] = 10.0 + (i % 30);
    }
    for (r = 0; r < REPEATS; ++r) {
        double a = now();
        for (k = 0; k < ROUNDS; ++k)
            for (i = 0; i < N; ++i) s += railgrip_model_mu_vt(dv[i], ddv[i], v[i], 5.0);
        double ns = (now() - a) / (ROUNDS * (double)N);
        if (ns < best_bare) best_bare = ns;
    }
    for (r = 0; r < REPEATS; ++r) {
        double a = now();
        for (k = 0; k < ROUNDS; ++k)
            for (i = 0; i < N; ++i) s += cloned(dv[i], ddv[i], v[i], 5.0);
        double ns = (now() - a) / (ROUNDS * (double)N);
        if (ns < best_cloned) best_cloned = ns;
    }
    if (argc > 1 && argv[1][0]) {
        void *lib = dlopen(argv[1], RTLD_NOW);
        if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 2; }
        callbacks cb = {0, calloc, free, 0, 0};
        void *c = ((inst_t)dlsym(lib, "fmi2Instantiate"))("h", 1, argv[2], "", &cb, 0, 0);
        real_t set = (real_t)dlsym(lib, "fmi2SetReal"), get = (real_t)dlsym(lib, "fmi2GetReal");
        step_t step = (step_t)dlsym(lib, "fmi2DoStep");
        if (!c) { fprintf(stderr, "fmi2Instantiate failed\n"); return 2; }
        ((setup_t)dlsym(lib, "fmi2SetupExperiment"))(c, 0, 0.0, 0.0, 0, 0.0);
        ((mode_t_)dlsym(lib, "fmi2EnterInitializationMode"))(c);
        ((mode_t_)dlsym(lib, "fmi2ExitInitializationMode"))(c);
        unsigned int vr[5] = {0, 1, 2, 3, 4}, vr_mu = (unsigned int)n_in;
        /* The inputs in the FMU's order, laid out before the clock starts (the bare header's
           loop reads its arrays directly too). */
        static double u[N][4];
        double mu, t = 0.0;
        for (i = 0; i < N; ++i) {
            double vals[4] = {dv[i], ddv[i], v[i], 5.0};
            int q;
            for (q = 0; q < n_in; q++) u[i][q] = vals[arg[q]];
        }
        /* with_step 1: fmi2SetReal + fmi2DoStep + fmi2GetReal; 0: without the step. */
        for (int with_step = 1; with_step >= 0; --with_step) {
            double *best = with_step ? &best_step : &best_set_get;
            for (r = 0; r < REPEATS; ++r) {
                double a = now();
                for (k = 0; k < ROUNDS; ++k)
                    for (i = 0; i < N; ++i) {
                        set(c, vr, (size_t)n_in, u[i]);
                        if (with_step) {
                            if (step(c, t, 0.01, 1) != 0) return 3;
                            t += 0.01;
                        }
                        get(c, &vr_mu, 1, &mu);
                        s += mu;
                    }
                double ns = (now() - a) / (ROUNDS * (double)N);
                if (ns < *best) *best = ns;
            }
        }
        ((free_t)dlsym(lib, "fmi2FreeInstance"))(c);
    }
    printf("%.2f %.2f %.2f %.2f %g\n", best_bare, best_step, best_set_get, best_cloned, s);
    return 0;
}
"""


def cpu() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("model", nargs="?", default=str(ROOT / "models/golden/synthetic_mlp.json"))
    ap.add_argument("--bin", default=str(ROOT / "target/release/railgrip"))
    ap.add_argument("--steps", type=int, default=20000)
    a = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="railgrip-fmu-overhead-"))
    fmu = work / "adhesion.fmu"
    subprocess.run([a.bin, "export", a.model, "--fmu", str(fmu)], check=True, stdout=subprocess.DEVNULL)
    with zipfile.ZipFile(fmu) as z:
        z.extractall(work / "fmu")
    from fmpy import read_model_description

    md = read_model_description(str(fmu))
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    lib = next((work / "fmu" / "binaries").rglob("adhesion.*"))
    (work / "harness.c").write_text(HARNESS)
    cc = os.environ.get("CC", "cc")
    macro = "-DRAILGRIP_MODEL_EXACT_FMA"
    builds = {
        "portable, exact fma() as library calls (-O2, no clones)": ["-O2", "-ffp-contract=off", macro],
        "native (-O2 -march=native)": ["-O2", "-march=native"],
    }
    print(f"model {a.model}; inputs {', '.join(inputs)}; CPU {cpu()}")
    for label, flags in builds.items():
        exe = work / "harness"
        subprocess.run([cc, "-std=c99", *flags, f"-I{work / 'fmu' / 'sources'}", "-o", str(exe),
                        str(work / "harness.c"), "-lm", "-ldl"], check=True)
        fmu_lib = str(lib) if label.startswith("portable") else ""
        which = {"dv_mps": "0", "ddv_mps2": "1", "v_mps": "2", "ambient_temperature_c": "3"}
        args = ",".join(which[n] for n in inputs)
        out = subprocess.run([str(exe), fmu_lib, md.guid, args], check=True,
                             capture_output=True, text=True).stdout.split()
        print(f"bare C header, {label}: {float(out[0]):.2f} ns per mu")
        if fmu_lib:
            print(f"bare C header, cloned for FMA as in the FMU's binary: {float(out[3]):.2f} ns per mu")
            print(f"C harness through the FMU: fmi2SetReal + fmi2DoStep + fmi2GetReal "
                  f"{float(out[1]):.2f} ns per step; fmi2SetReal + fmi2GetReal {float(out[2]):.2f} ns")

    import numpy as np
    from fmpy import extract, simulate_fmu
    from fmpy.fmi2 import FMU2Slave

    n = a.steps
    rows = np.zeros(n, dtype=[("time", float)] + [(c, float) for c in inputs])
    rows["time"] = np.arange(n, dtype=float)
    rows["dv_mps"] = np.linspace(0.0, 4.0, n)
    if "ddv_mps2" in inputs:
        rows["ddv_mps2"] = np.sin(np.arange(n) * 0.01) * 3.0
    rows["v_mps"] = np.linspace(40.0, 1.0, n)
    if "ambient_temperature_c" in inputs:
        rows["ambient_temperature_c"] = 5.0
    t = time.perf_counter()
    simulate_fmu(str(fmu), fmi_type="CoSimulation", start_time=0.0, stop_time=float(n - 1),
                 output_interval=1.0, input=rows, output=["mu"], validate=False)
    per = (time.perf_counter() - t) / (n - 1)
    print(f"FMPy simulate_fmu (co-simulation, {n - 1} steps, input signals): {per * 1e6:.1f} µs per step")
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="loop")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    vrs = list(range(len(inputs)))
    mu_vr = [len(inputs)]
    t = time.perf_counter()
    for k in range(n):
        s.setReal(vrs, [float(rows[c][k]) for c in inputs])
        s.doStep(currentCommunicationPoint=float(k), communicationStepSize=1.0)
        s.getReal(mu_vr)
    per = (time.perf_counter() - t) / n
    print(f"FMPy FMU2Slave from Python (setReal, doStep, getReal): {per * 1e6:.1f} µs per step")
    s.terminate()
    s.freeInstance()
    import fmpy

    print(f"fmpy {fmpy.__version__}, numpy {np.__version__}, Python {platform.python_version()}; "
          f"files in {work}")


if __name__ == "__main__":
    sys.exit(main())
