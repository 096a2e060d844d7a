"""Comparison grids: a config error inside a grid is an error before anything runs (exit 2), an impossible
combination a skip; duplicate values; sizes; ``--budget``; and ``--set`` overrides."""
from __future__ import annotations


from tools.catalogue import fixtures as fx
from tools.catalogue.core import case


def _grid(edit=None, **axes):
    def setup(ws):
        part = fx.grid_part(**axes)
        if edit:
            edit(part, ws)
        fx.study(ws, parts={"grid": part}, name="g")
    return setup


def _args(*more):
    return lambda ws: ["run", ws.path("configs", "g.yaml"), "--out", ws.out, "--quiet", *more]


def _exp(part):
    return part["scenarios"]["elbow"]["experiment"]


def _set(path, value):
    def edit(part, ws):
        obj = part
        keys = path.split(".")
        for k in keys[:-1]:
            obj = obj[k]
        obj[keys[-1]] = value(ws) if callable(value) else value
    return edit


def _del(path):
    def edit(part, ws):
        obj = part
        keys = path.split(".")
        for k in keys[:-1]:
            obj = obj[k]
        obj[keys[-1] + "_typo"] = obj.pop(keys[-1])
    return edit


S = "scenarios.elbow.experiment"
kind = "grid"
case(kind, "typo'd key duraton", setup=_grid(lambda p, ws: _exp(p).update(duraton=_exp(p).pop("duration"))),
     args=_args(), names=r"duraton")
case(kind, "typo'd key Kk", setup=_grid(lambda p, ws: _exp(p)["joint"].update(Kk=_exp(p)["joint"].pop("K"))),
     args=_args(), names=r"Kk")
case(kind, "typo'd key in a perturbation of the axis", args=_args(), names=r"cutof",
     setup=_grid(lambda p, ws: p["perturbations"].update(fn={"kind": "filtered_noise", "cutof": "20 Hz"}),
                 perturbation=["fn"]))
case(kind, "negative duration", setup=_grid(_set(S + ".duration", "-6 s")), args=_args(), names=r"duration")
case(kind, "zero duration", setup=_grid(_set(S + ".duration", "0 s")), args=_args(), names=r"duration")
case(kind, "zero inertia", setup=_grid(_set(S + ".joint.I", 0)), args=_args(), names=r"\bI\b")
case(kind, "negative inertia", setup=_grid(_set(S + ".joint.I", -0.01)), args=_args(), names=r"\bI\b")
case(kind, "unknown variation shape", setup=_grid(_set("variations.square", {"shape": "sqare"})), args=_args(),
     names=r"sqare")
case(kind, "variation with an unknown key", setup=_grid(_set("variations.square", {"shape": "square", "phse": 1})),
     args=_args(), names=r"phse")
case(kind, "fs above fs_sim (axis)", setup=_grid(fs=["5 kHz"]), args=_args(), names=r"fs")
case(kind, "fs above fs_sim (scenario)", setup=_grid(_set(S + ".acquisition.fs", "4 kHz")), args=_args(),
     names=r"fs")
case(kind, "negative cutoff", setup=_grid(_set(S + ".perturbation.cutoff", "-20 Hz")), args=_args(),
     names=r"cutoff")
case(kind, "negative cutoff in an axis perturbation", args=_args(), names=r"cutoff",
     setup=_grid(lambda p, ws: p["perturbations"].update(fn={"kind": "filtered_noise", "cutoff": "-5 Hz"}),
                 perturbation=["fn"]))
case(kind, "unknown apparatus kind", setup=_grid(_set(S + ".apparatus.kind", "robot")), args=_args(),
     names=r"robot")
case(kind, "wrong unit for fs_sim", setup=_grid(_set(S + ".fs_sim", "2 kg")), args=_args(), names=r"fs_sim")


def _profile_variation(make, **extra):
    def edit(part, ws):
        path = make(ws)
        part["variations"]["square"] = {"shape": "file", "path": str(path), **extra}
    return edit


case(kind, "missing profile file", setup=_grid(_profile_variation(lambda ws: ws.path("nope.csv"))),
     args=_args(), names=r"nope\.csv")
case(kind, "wrong sha256 of a profile", args=_args(), names=r"sha|SHA",
     setup=_grid(_profile_variation(lambda ws: fx.profile_csv(ws.path("k.csv")), sha256="0" * 64)))
case(kind, "profile that makes K negative", args=_args(), names=r"\bK\b|k\.csv",
     setup=_grid(_profile_variation(lambda ws: fx.profile_csv(ws.path("k.csv"), low=-10))))
case(kind, "profile with a bad header", args=_args(), names=r"k\.csv",
     setup=_grid(_profile_variation(lambda ws: (ws.path("k.csv").write_text("t,v\n0,1\n9,2\n"), ws.path("k.csv"))[1])))


def _mujoco_unstable(part, ws):
    _exp(part)["joint"]["K"] = 2.0e7
    part["scenarios"]["elbow"]["stiffness"] = {"mean": 2.0e7, "amplitude": 1.0e6, "period": "3 s"}
    part["grid"]["backend"] = ["mujoco"]


case(kind, "unstable MuJoCo step", setup=_grid(_mujoco_unstable), args=_args(), names=r"unstable|step",
     timeout=120)
case(kind, "unknown backend on the axis", setup=_grid(backend=["mujocoo"]), args=_args(), names=r"mujocoo")


def _skips_skirt(ws, o):
    import pandas as pd

    rows = pd.read_csv(ws.out / "cat" / "cases.csv")
    sk = rows[rows["metric"] == "skipped"]
    if not len(sk) or not sk["reason"].astype(str).str.contains("multisine").all():
        return "skirt on PRBS was not reported as a skipped combination"
    return None


case(kind, "skirt on PRBS is a skip", expect="ok", check=_skips_skirt, timeout=180,
     setup=_grid(estimator=["ibk_spectral", "skirt"], perturbation=["prbs"], noise=[0.05]), args=_args())


def _fs_300(part, ws):
    part["grid"]["fs"] = ["native", "300 Hz"]


case(kind, "fs not dividing fs_sim is a skip", expect="ok", setup=_grid(_fs_300, noise=[0.05]), timeout=180,
     args=_args(), check=lambda ws, o: None if "does not divide" in
     (ws.out / "cat" / "cases.csv").read_text() else "the 300 Hz combination was not reported as skipped")
case(kind, "duplicate values [1, 1.0]", setup=_grid(noise=[1, 1.0]), args=_args(), names=r"noise.*(twice|duplicate|same)")
case(kind, "duplicate values [100 Hz, 0.1 kHz]", setup=_grid(fs=["100 Hz", "0.1 kHz"]), args=_args(),
     names=r"fs.*(twice|duplicate|same)")
case(kind, "duplicate values [0.05, 5e-2]", setup=_grid(noise=[0.05, 5.0e-2]), args=_args(),
     names=r"noise.*(twice|duplicate|same)")
case(kind, "duplicate estimator", setup=_grid(estimator=["ibk_spectral", "ibk_spectral"]), args=_args(),
     names=r"estimator.*(twice|duplicate|same)")
case(kind, "unknown axis", setup=_grid(nois=[0]), args=_args(), names=r"nois")
case(kind, "axis not a list", setup=_grid(noise=0.1), args=_args(), names=r"noise")
case(kind, "empty axis", setup=_grid(noise=[]), args=_args(), names=r"noise")
case(kind, "unknown estimator on the axis", setup=_grid(estimator=["ibk_spectrall"]), args=_args(),
     names=r"ibk_spectrall")
case(kind, "negative noise", setup=_grid(noise=[-0.1]), args=_args(), names=r"noise")
case(kind, "noise NaN", setup=_grid(noise=[float("nan")]), args=_args(), names=r"noise")
case(kind, "fs of 0 Hz", setup=_grid(fs=["0 Hz"]), args=_args(), names=r"fs")
case(kind, "fs not a rate", setup=_grid(fs=["fast"]), args=_args(), names=r"fs")
case(kind, "negative budget", setup=_grid(_set("budget", -1)), args=_args(), names=r"budget")
case(kind, "variation axis without scenario stiffness", setup=_grid(lambda p, ws: p["scenarios"]["elbow"].pop("stiffness")),
     args=_args(), names=r"stiffness")
case(kind, "seeds 0 in a grid", setup=_grid(_set("seeds", 0)), args=_args(), names=r"seeds")


def _huge(part, ws):
    part["grid"]["noise"] = [round(i * 1e-4, 6) for i in range(1000)]
    part["grid"]["fs"] = [f"{i} Hz" for i in range(1, 1001)]


case(kind, "grid of 10^6 combinations", setup=_grid(_huge), args=_args(), timeout=90,
     names=r"(combinations|cases).*(more than|limit|at most)")
case(kind, "grid of 10^6 combinations with --budget nan", setup=_grid(_huge), args=_args("--budget", "nan"),
     timeout=90, names=r"budget|combinations")
case(kind, "grid of 10^6 combinations with --yes", setup=_grid(_huge), args=_args("--yes"), timeout=90,
     names=r"(combinations|cases).*(more than|limit|at most)")
case(kind, "--budget nan", setup=_grid(), args=_args("--budget", "nan"), names=r"budget")
case(kind, "--budget 0", setup=_grid(), args=_args("--budget", "0"), names=r"budget")
case(kind, "--budget -5", setup=_grid(), args=_args("--budget", "-5"), names=r"budget")
case(kind, "--budget abc", setup=_grid(), args=_args("--budget", "abc"), names=r"budget")

kind = "set"


def _fit(ws):
    fx.study(ws, parts={"fit": fx.fit_part(), "grid": fx.grid_part()}, name="s")


def _sargs(*sets):
    return lambda ws: ["run", ws.path("configs", "s.yaml"), "--out", ws.out, "--quiet",
                       *[x for s in sets for x in ("--set", s)]]


for text, names in [("fit.seeds", r"PART\.KEY=VALUE"), ("nope.seeds=2", r"nope"), ("fit.seeds=abc", r"seeds"),
                    ("fit.experiment.duration=-1 s", r"duration"), ("fit.nonexistent=1", r"nonexistent"),
                    ("fit.experiment.joint.I=0", r"\bI\b"), ("*.seeds=0", r"seeds"), ("fit.seeds=1000000000", r"seeds"),
                    ("fit.seeds=[1,", r"fit\.seeds"), ("grid.grid.noise=[1, 1.0]", r"noise"),
                    ("grid.grid.fs=[100 Hz, 0.1 kHz]", r"fs"), ("grid.grid.estimator=[nope]", r"nope"),
                    ("fit.experiment.acquisition.fs=3 kHz", r"fs"), ("fit.experiment.perturbation.cutoff=-1 Hz", r"cutoff"),
                    ("fit.experiment.joint.K={shape: sinee}", r"sinee"), ("fit.seeds.x=1", r"seeds"),
                    ("grid.scenarios.elbow.experiment.duraton=6 s", r"duraton"), ("fit..seeds=1", r"PART\.KEY"),
                    ("=3", r"PART\.KEY"), ("fit.estimators.ibk_spectral.fmax=-3 Hz", r"fmax")]:
    case("set", f"--set {text}", setup=_fit, args=_sargs(text), names=names)
case("set", "--set the same key twice (last wins or refused)", expect="ok", setup=_fit,
     args=_sargs("fit.seeds=1", "fit.seeds=1", "grid.grid.noise=[0.05]"), timeout=180)
