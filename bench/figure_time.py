"""What the figures cost in the commands that draw them: each command run as a process of its
own (``cli.main``, as a user runs it) with every figure function of ``thrustwalk_cli.plots``
and ``plots.style.render`` wrapped by a CPU timer (``time.process_time``; nothing else
changed). Per figure: its build (the plot function, ``tight_layout`` included) and each saved
format; per command: the process's CPU (user + system) at its end.

    python bench/figure_time.py [NAME ...] [--runs N]    (not part of ``make bench``)

Commands by name (the table ``COMMANDS`` below: realistic sweeps on the bundled robots);
``--runs N`` runs each N times, interleaved, and prints every run (the machine may be shared:
compare the least of interleaved runs). Run it with ``PYTHONPATH`` set to the checkout to
measure.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time

from timing import run_cli_here

COMMANDS = {
    "limit-cycle": ["limit-cycle", "rabbit", "rabbit_walk", "--thrust", "0:-50:-0.25"],
    "limit-cycle-3link": ["limit-cycle", "three_link", "three_link_walk",
                          "--thrust", "0:-50:-0.25"],
    "energy": ["energy", "rabbit", "rabbit_walk", "--thrust", "0:-50:-0.25"],
    "feasibility": ["feasibility", "rabbit", "rabbit_walk", "--thrust", "0:-50:-1"],
    "slope": ["slope", "three_link", "three_link_walk", "--slope", "-0.2:0.2:0.01",
              "--thrust", "0:-50:-2"],
    "shape": ["shape", "three_link", "three_link_walk", "--knots", "0,?,?,1",
              "--pattern", "k*(j-2)", "--k", "0:50:0.5"],
    "simulate": ["simulate", "rabbit", "rabbit_walk", "--steps", "30", "--thrust-model",
                 "second-order", "--thrust", "0:-50:-2", "--wn", "2", "--xi", "1"],
    "stability": ["stability", "three_link", "three_link_walk", "--thrust-model",
                  "second-order", "--wn", "2", "--xi", "0.7", "--thrust", "-20",
                  "--vary", "wn=0.5:50:log20"],
    "control": ["control", "three_link", "three_link_walk", "--reference", "speed",
                "--profile", "0:0.8,10:1.4,25:1.0", "--knots", "0,0.5,1", "--steps", "40",
                "--mu", "0.7"],
    "robustness": ["robustness", "three_link", "three_link_walk", "--push-impulse",
                   "-30:30:4", "--push-phase", "0:1:0.1", "--strategy",
                   "none,constant:-20", "--steps", "6"],
    "rough-ground": ["rough-ground", "three_link", "three_link_walk", "--sigma",
                     "0.002:0.005:0.001", "--strategy", "none,constant:-20", "--trials", "20",
                     "--cap", "200"],
    "design-gait": ["design-gait", "tests/data/walker5.yaml", "--target-speed", "0.6",
                    "--name", "fig"],
    "sweep": ["sweep", "sweeps/thrust_torso_mass.yaml"],
}


def _wrap() -> dict:
    """Wrap the figure functions and ``render``; returns the record they fill."""
    import importlib
    import pkgutil

    from matplotlib.figure import Figure

    import thrustwalk_cli.plots as plots
    from thrustwalk_cli.plots import style

    rec: dict = {"build": {}, "render": {}, "names": {}}
    depth = [0]

    def wrap_builder(module, name, inner):
        def timed(*a, **k):
            depth[0] += 1
            t0 = time.process_time()
            try:
                out = inner(*a, **k)
            finally:
                depth[0] -= 1
            if depth[0] == 0 and isinstance(out, Figure):
                key = f"{module.__name__.rsplit('.', 1)[1]}.{name}"
                rec["build"].setdefault(key, []).append(time.process_time() - t0)
                rec["names"][id(out)] = key
            return out
        timed.__wrapped__ = inner
        return timed

    for info in pkgutil.iter_modules(plots.__path__):
        if info.name in ("style", "mujoco"):
            continue
        module = importlib.import_module(f"thrustwalk_cli.plots.{info.name}")
        for name, obj in list(vars(module).items()):
            if callable(obj) and getattr(obj, "__module__", None) == module.__name__ \
                    and not isinstance(obj, type):
                setattr(module, name, wrap_builder(module, name, obj))

    inner_render = style.render

    def render(fig, fmt, *a, **k):
        t0 = time.process_time()
        try:
            return inner_render(fig, fmt, *a, **k)
        finally:
            key = f"{rec['names'].get(id(fig), '?')} {fmt}"
            rec["render"].setdefault(key, []).append(time.process_time() - t0)

    style.render = render
    return rec


def _child(args: list[str]) -> None:
    rec = _wrap()
    cpu = run_cli_here(args)
    rec.pop("names")
    rec["cpu"] = cpu
    print("FIGTIME " + json.dumps(rec), file=sys.stderr)


def _run(name: str) -> dict:
    with tempfile.TemporaryDirectory() as out:
        p = subprocess.run([sys.executable, __file__, "--child", *COMMANDS[name], "--out",
                            f"{out}/r", "-q"], capture_output=True, text=True)
    line = [x for x in p.stderr.splitlines() if x.startswith("FIGTIME ")]
    if not line:
        raise RuntimeError(f"{name}: {p.stderr[-2000:]}")
    return json.loads(line[-1][8:])


def main(argv: list[str]) -> None:
    runs = 1
    if "--runs" in argv:
        i = argv.index("--runs")
        runs = int(argv[i + 1])
        argv = argv[:i] + argv[i + 2:]
    names = argv or list(COMMANDS)
    for r in range(runs):
        for name in names:
            rec = _run(name)
            figs = sum(sum(v) for v in rec["build"].values()) + \
                sum(sum(v) for v in rec["render"].values())
            print(f"{name} run {r + 1}: process {rec['cpu']:.2f} s, figures {figs:.2f} s")
            for key, v in rec["build"].items():
                print(f"    build  {key:40s} {sum(v):6.3f} s" + (f" ({len(v)})" if len(v) > 1
                                                                  else ""))
            for key, v in rec["render"].items():
                print(f"    render {key:40s} {sum(v):6.3f} s" + (f" ({len(v)})" if len(v) > 1
                                                                  else ""))


if __name__ == "__main__":
    if sys.argv[1:2] == ["--child"]:
        _child(sys.argv[2:])
    else:
        main(sys.argv[1:])
