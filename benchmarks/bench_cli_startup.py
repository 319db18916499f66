"""Start-up time of the ``mirrorlab`` command (whole processes, as a user waits for them).

Run: ``python benchmarks/bench_cli_startup.py [--repeats 15]``

Each command is started ``--repeats`` times as a fresh process, interleaved with the baselines
so that a busy machine slows them alike; printed is the median wall time of each and its ratio to
two baselines measured in the same run: ``python -c pass`` (the interpreter alone) and
``python -c "import numpy"`` (what any scientific command pays at least). Goal: ``--version``
and ``--help`` below 0.3 s on an idle machine, i.e. about the cost of importing numpy, because
they import no plugin (the sub-command table is read without importing plugins, see
``mirrorlab.core.cli.commands``). Commands that work on a session import only the plugins they
use (the registry reads what each plugin declares, ``mirrorlab.core.registry``): ``session info``
none, ``analyze derivatives`` and ``kinematics --help`` the kinematics plugin, ``run --check`` of
the demo's recording recipe the plugins it names. ``plugins`` imports every plugin and is shown
for contrast.

The ``mirrorlab`` script next to this interpreter is used (``.venv/bin/mirrorlab``). Exit code 0.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

GOAL_S = 0.3


def _script() -> str:
    script = Path(sys.executable).with_name("mirrorlab")
    if not script.exists():
        raise SystemExit(f"no mirrorlab script next to {sys.executable}; install mirrorlab into this environment")
    return str(script)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=15, help="runs per command (median reported)")
    args = ap.parse_args()
    mirrorlab = _script()
    work = Path(tempfile.mkdtemp())
    session = work / "small.h5"
    subprocess.run([mirrorlab, "session", "new", str(session)], stdout=subprocess.DEVNULL, check=True)
    recipe = Path(__file__).resolve().parents[1] / "sessions" / "rssr_acquire.toml"
    commands = {
        "python -c pass": [sys.executable, "-c", "pass"],
        "python -c 'import numpy'": [sys.executable, "-c", "import numpy"],
        "mirrorlab --version": [mirrorlab, "--version"],
        "mirrorlab --help": [mirrorlab, "--help"],
        "mirrorlab session info FILE": [mirrorlab, "session", "info", str(session)],
        "mirrorlab kinematics --help": [mirrorlab, "kinematics", "--help"],
        "mirrorlab analyze derivatives -h": [mirrorlab, "analyze", "derivatives", "--help"],
        "mirrorlab run ... --check": [mirrorlab, "run", str(recipe), "--check"],
        "mirrorlab plugins": [mirrorlab, "plugins"],
    }
    times: dict[str, list[float]] = {name: [] for name in commands}
    for _ in range(args.repeats):
        for name, cmd in commands.items():  # interleaved: load changes hit every command alike
            t0 = time.perf_counter()
            subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
            times[name].append(time.perf_counter() - t0)
    median = {name: statistics.median(t) for name, t in times.items()}
    bare, numpy_ = median["python -c pass"], median["python -c 'import numpy'"]
    print(f"{'command':34s} {'median s':>9s} {'min s':>7s} {'x python':>9s} {'x numpy':>8s}")
    for name, t in median.items():
        print(f"{name:34s} {t:9.3f} {min(times[name]):7.3f} {t / bare:9.2f} {t / numpy_:8.2f}")
    worst = max(median["mirrorlab --version"], median["mirrorlab --help"])
    print(f"--version/--help: {worst:.3f} s (goal < {GOAL_S} s on an idle machine; "
          f"{worst / numpy_:.2f} x the numpy import baseline)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
