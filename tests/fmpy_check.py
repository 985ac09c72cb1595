"""An FMU through FMPy, for tests/fmu.rs: FMPy's validation, a co-simulation and a Model Exchange
run on input signals, and the error statuses of bad inputs.

    fmpy_check.py FMU INPUT.csv OUT_PREFIX [--build]

INPUT.csv has a header row and one row per communication step: any of the FMU's inputs
(dv_mps, ddv_mps2, v_mps, ambient_temperature_c); row k is applied at time k s (whole seconds,
so FMPy's linear interpolation of the inputs meets every row exactly). Writes OUT_PREFIX.cs.csv
and OUT_PREFIX.me.csv (time,mu per communication point, floats as repr: exact) and prints one
With --build the FMU is a source FMU: FMPy builds its binary from sources/ first, as an
importing tool would (CMake, Release), and the rest runs on that build. Prints one
line per finding: `problem: ...` (validation), `nan_dv: ...`, `inf_ddv: ...` (error statuses),
`nan_v: MU`, `nan_t: MU` (μ at slip 0.5 m/s, slip rate 0.3 m/s2 and speed NaN at 20 C, or speed
30 m/s at temperature NaN).
"""

import math
import os
import sys

import numpy as np
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu


def write(path, result):
    with open(path, "w") as f:
        f.write("time,mu\n")
        for t, mu in zip(result["time"], result["mu"]):
            f.write(f"{float(t)!r},{float(mu)!r}\n")


def main():
    fmu, inp, prefix = sys.argv[1:4]
    for p in validate_fmu(fmu):
        print("problem:", p)
    if "--build" in sys.argv[4:]:
        from fmpy.build import build_platform_binary

        unzipped = extract(fmu)
        build_platform_binary(unzipped)
        fmu = unzipped
    md = read_model_description(fmu)
    names = [v.name for v in md.modelVariables if v.causality == "input"]
    data = np.genfromtxt(inp, delimiter=",", names=True, dtype=np.float64)
    given = [c for c in names if c in data.dtype.names]
    n = len(data)
    rows = np.zeros(n, dtype=[("time", np.float64)] + [(c, np.float64) for c in given])
    rows["time"] = np.arange(n, dtype=np.float64)
    for c in given:
        rows[c] = data[c]
    common = dict(start_time=0.0, stop_time=float(n - 1), output_interval=1.0, input=rows,
                  output=["mu"], validate=False)
    write(prefix + ".cs.csv", simulate_fmu(fmu, fmi_type="CoSimulation", **common))
    write(prefix + ".me.csv", simulate_fmu(fmu, fmi_type="ModelExchange", solver="Euler",
                                           step_size=1.0, **common))

    # Bad inputs, each on a fresh instance: the status must be an error, never a crash.
    unzipped = fmu if os.path.isdir(fmu) else extract(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}

    def instance():
        s = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="check")
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        return s

    for label, name, value in (("nan_dv", "dv_mps", math.nan), ("inf_ddv", "ddv_mps2", math.inf)):
        if name not in vr:
            continue
        s = instance()
        s.setReal([vr[name]], [value])
        try:
            s.doStep(currentCommunicationPoint=0.0, communicationStepSize=1.0)
            print(f"{label}: doStep ok")
        except Exception as e:  # FMPy raises on fmi2Error
            print(f"{label}: doStep error: {e}")
        try:
            print(f"{label}: getReal ok {s.getReal([vr['mu']])[0]!r}")
        except Exception as e:
            print(f"{label}: getReal error: {e}")
        s.freeInstance()
    # NaN speed or temperature: the file's reference (or base) values, as the Rust evaluator
    # has them (tests/fmu.rs compares): slip 0.5 m/s, slip rate 0.3 m/s2, then speed NaN at
    # 20 C, and speed 30 m/s at temperature NaN.
    for label, v, t in (("nan_v", math.nan, 20.0), ("nan_t", 30.0, math.nan)):
        s = instance()
        values = {"dv_mps": 0.5, "ddv_mps2": 0.3, "v_mps": v, "ambient_temperature_c": t}
        names_in = [n for n in values if n in vr]
        s.setReal([vr[n] for n in names_in], [values[n] for n in names_in])
        print(f"{label}: {s.getReal([vr['mu']])[0]!r}")
        s.terminate()
        s.freeInstance()

    # FMU states: get one, change the inputs, set it back: mu as before; and through bytes.
    s = instance()
    s.setReal([vr["dv_mps"]], [0.7])
    before = s.getReal([vr["mu"]])[0]
    state = s.getFMUstate()
    blob = s.serializeFMUstate(state)
    s.setReal([vr["dv_mps"]], [2.0])
    changed = s.getReal([vr["mu"]])[0]
    s.setFMUstate(state)
    restored = s.getReal([vr["mu"]])[0]
    s.setReal([vr["dv_mps"]], [2.0])
    again = s.deSerializeFMUstate(blob)
    s.setFMUstate(again)
    from_bytes = s.getReal([vr["mu"]])[0]
    s.freeFMUstate(state)
    s.freeFMUstate(again)
    print(f"state: {before!r} {changed!r} {restored!r} {from_bytes!r}")
    s.terminate()
    s.freeInstance()

if __name__ == "__main__":
    main()
