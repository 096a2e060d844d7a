"""Study files and names: encodings, resource bombs, odd files, ``published:``, reserved and unsafe ids."""
from __future__ import annotations

import os

import yaml

from tools.catalogue import fixtures as fx
from tools.catalogue.core import case


def _raw(text: bytes | str, name: str = "raw.yaml"):
    def setup(ws):
        p = ws.path(name)
        p.write_bytes(text if isinstance(text, bytes) else text.encode())
    return setup


def _run(name: str = "raw.yaml", *more):
    return lambda ws: ["run", ws.path(name), "--out", ws.out, "--quiet", *more]


def _edited(edit, study_id: str = "cat"):
    def setup(ws):
        fx.study(ws, study_id=study_id, edit=edit, name="s")
    return setup


def _study_text(ws) -> str:
    fx.study(ws, name="s")
    return ws.path("configs", "s.yaml").read_text()


def _encoded(encoding: str, bom: bool = False):
    def setup(ws):
        text = _study_text(ws).replace("catalogue study", "catalogue study of Müller and Señor")
        data = text.encode(encoding)
        ws.path("raw.yaml").write_bytes((b"\xef\xbb\xbf" if bom else b"") + data)
    return setup


kind = "yaml"
case(kind, "latin-1 study file", setup=_encoded("latin-1"), args=_run(), names=r"raw\.yaml.*(UTF-8|encod)")
case(kind, "UTF-16 with BOM", setup=_encoded("utf-16"), args=_run(), names=r"raw\.yaml.*(UTF|encod)")
case(kind, "UTF-16-LE without BOM", setup=_encoded("utf-16-le"), args=_run(), names=r"raw\.yaml")
case(kind, "UTF-8 with BOM runs", expect="ok", setup=_encoded("utf-8", bom=True), args=_run())
case(kind, "binary garbage", setup=_raw(bytes(range(256)) * 4), args=_run(), names=r"raw\.yaml")
case(kind, "empty file", setup=_raw(""), args=_run(), names=r"raw\.yaml")
case(kind, "top level is a list", setup=_raw("- a\n- b\n"), args=_run(), names=r"raw\.yaml.*mapping")
case(kind, "top level is a number", setup=_raw("42\n"), args=_run(), names=r"raw\.yaml.*mapping")
case(kind, "tab indentation", setup=_raw("study: x\n\tparts: {}\n"), args=_run(), names=r"raw\.yaml")
case(kind, "unclosed bracket", setup=_raw("study: [x\n"), args=_run(), names=r"raw\.yaml")
case(kind, "duplicate key", setup=_raw("study: a\nstudy: b\n"), args=_run(), names=r"duplicate key")
alias_bomb = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{c}: &{c} [{', '.join('*' + p for _ in range(9))}]\n" for p, c in zip("abcdefgh", "bcdefghi"))


def _bombed(where: str):
    """A valid study with a reading whose ``alternatives`` hold the anchors (9 levels of 9 aliases: 387
    million values once expanded), and ``where`` (the reading's text, or the study id) an alias of the last."""
    def setup(ws):
        text = _study_text(ws)
        bomb = "".join("      " + ln + "\n" for ln in alias_bomb.splitlines())
        reading = ("readings:\n  - id: R1\n    topic: t\n    passage: p\n    alternatives:\n" + bomb
                   + "    reading: " + ("*i" if where == "reading" else "r") + "\n")
        if where == "id":
            text = text.replace("study: cat", "study: *i", 1)
        ws.path("raw.yaml").write_text(reading + text)
    return setup


case(kind, "alias bomb (anchors of anchors) in a reading", setup=_bombed("reading"), args=_run(),
     timeout=60, names=r"raw\.yaml.*(alias|anchor|large|limit)")
case(kind, "alias bomb as the study id", setup=_bombed("id"), args=_run(), timeout=60,
     names=r"raw\.yaml.*(alias|anchor|large|limit)")
case(kind, "50 MB study file", timeout=90, names=r"raw\.yaml.*(MB|large|size|limit)",
     setup=lambda ws: ws.path("raw.yaml").write_text(_study_text(ws) + "# " + "x" * 50_000_000 + "\n"),
     args=_run())
case(kind, "50 MB of list items", timeout=90, names=r"raw\.yaml.*(MB|large|size|limit)",
     setup=lambda ws: ws.path("raw.yaml").write_text("study: x\nbig:\n" + "- 1\n" * 12_500_000), args=_run())
case(kind, "deeply nested flow lists", timeout=60, names=r"raw\.yaml.*(nest|deep|depth)",
     setup=_raw("study: " + "[" * 20000 + "]" * 20000 + "\n"), args=_run())
case(kind, "deeply nested mappings", timeout=60, names=r"raw\.yaml.*(nest|deep|depth)",
     setup=_raw("".join(" " * i + f"k{i}:\n" for i in range(3000)) + " " * 3000 + "v: 1\n"), args=_run())
case(kind, "deeply nested flow mappings", timeout=60, names=r"raw\.yaml.*(nest|deep|depth)",
     setup=_raw("study: " + "{a: " * 5000 + "1" + "}" * 5000 + "\n"), args=_run())
case(kind, "study file is a symlink to /dev/zero", timeout=30, names=r"raw\.yaml.*(regular|not a file|device)",
     setup=lambda ws: os.symlink("/dev/zero", ws.path("raw.yaml")), args=_run())
case(kind, "study file is a FIFO", timeout=30, names=r"raw\.yaml.*(regular|not a file|FIFO|pipe)",
     setup=lambda ws: os.mkfifo(ws.path("raw.yaml")), args=_run())
case(kind, "study file is a folder", setup=lambda ws: ws.path("raw.yaml").mkdir(), args=_run(),
     names=r"raw\.yaml")
case(kind, "study file missing", args=_run("nope.yaml"), names=r"nope\.yaml.*not found")
case(kind, "unknown study id", args=["run", "no_such_study", "--quiet"], names=r"no_such_study")
case(kind, "study file not readable (permissions)", needs=lambda: "root reads anything" if os.geteuid() == 0 else None,
     setup=lambda ws: (fx.study(ws, name="s"), os.chmod(ws.path("configs", "s.yaml"), 0)),
     args=lambda ws: ["run", ws.path("configs", "s.yaml"), "--out", ws.out, "--quiet"], names=r"s\.yaml")


def _experiment(**changes):
    """A study whose one part's experiment has ``changes`` (several mistakes: each is one line of the error)."""
    def setup(ws):
        fx.study(ws, parts={"fit": fx.fit_part(experiment=dict(fx.EXPERIMENT, **changes))}, name="s")
    return setup


def s_yaml(ws):
    """``jointbench run`` of the study file ``s.yaml``."""
    return ["run", ws.path("configs", "s.yaml"), "--out", ws.out, "--quiet"]


# every error of a file at once, one line each, each naming the file (core.clean_error)
case(kind, "several errors in one experiment", args=s_yaml, names=r"s\.yaml.*fs_sim",
     setup=_experiment(joint={"model": "second_order", "I": "heavy", "B": 0.5, "K": -50}, fs_sim="2 kg"))
case(kind, "several errors in one profile", args=s_yaml, names=r"s\.yaml.*initial",
     setup=_experiment(joint={"model": "time_varying", "I": 0.01, "B": 0.5, "K": {"shape": "ramp", "end": 80}}))

kind = "published"


def _pub(value):
    def edit(d):
        d["published"] = value
    return edit


case(kind, "published: 123", setup=_edited(_pub(123)), args=s_yaml, names=r"published")
case(kind, "published: a list", setup=_edited(_pub(["a.yaml", "b.yaml"])), args=s_yaml, names=r"published")
case(kind, "published: a mapping", setup=_edited(_pub({"x": 1})), args=s_yaml, names=r"published")
case(kind, "published: null", setup=_edited(_pub(None)), args=s_yaml, names=r"published")
case(kind, "published: true", setup=_edited(_pub(True)), args=s_yaml, names=r"published")
case(kind, "published: missing file", setup=_edited(_pub("nowhere/p.yaml")), args=s_yaml, names=r"p\.yaml")
case(kind, "published: a folder", setup=_edited(_pub("/tmp")), args=s_yaml, names=r"/tmp|published")
case(kind, "published: /dev/zero", timeout=30, setup=_edited(_pub("/dev/zero")), args=s_yaml,
     names=r"/dev/zero")


def _pub_file(text: bytes):
    def setup(ws):
        fx.study(ws, name="s")
        ws.path("configs", "s_published.yaml").write_bytes(text)
    return setup


case(kind, "published file: checks is a number", setup=_pub_file(b"study: cat\nsource: x\nchecks: 5\n"),
     args=s_yaml, names=r"checks")
case(kind, "published file: latin-1", args=s_yaml, names=r"s_published\.yaml",
     setup=_pub_file("study: cat\nsource: Müller\nchecks: []\n".encode("latin-1")))
case(kind, "published file: a check is a string", args=s_yaml, names=r"checks",
     setup=_pub_file(b"study: cat\nsource: x\nchecks: [oops]\n"))
case(kind, "published file: low is text", args=s_yaml, names=r"low",
     setup=_pub_file(yaml.safe_dump({"study": "cat", "source": "x", "checks": [dict(fx.PUBLISHED["checks"][0],
                                                                                    low="abc")]}).encode()))

kind = "names"


def _sid(study_id):
    return dict(setup=_edited(lambda d: None, study_id=study_id), args=s_yaml)


case(kind, "study id 'cache' (reserved folder)", names=r"cache.*reserved|reserved.*cache", **_sid("cache"))
case(kind, "study id 'nightly' (reserved folder)", names=r"nightly.*reserved|reserved.*nightly", **_sid("nightly"))
case(kind, "study id 'history.sqlite' (the history file)", names=r"history\.sqlite", **_sid("history.sqlite"))
case(kind, "study id '..'", names=r"study", **_sid(".."))
case(kind, "study id '../escape'", names=r"study", **_sid("../escape"))
case(kind, "study id with a slash", names=r"study", **_sid("a/b"))
case(kind, "study id empty", names=r"study", **_sid(""))
case(kind, "study id absolute path", names=r"study", **_sid("/tmp/x"))
case(kind, "study id of 300 characters", names=r"study", **_sid("x" * 300))
case(kind, "study id with a newline", names=r"study", **_sid("a\nb"))
case(kind, "study id 'CACHE' (case-folding file systems)", names=r"CACHE.*reserved", **_sid("CACHE"))
case(kind, "--out is a file", setup=lambda ws: (fx.study(ws, name="s"), ws.path("f").write_text("x")),
     args=lambda ws: ["run", ws.path("configs", "s.yaml"), "--out", ws.path("f"), "--quiet"], names=r"f")
case(kind, "--out under /dev/null", setup=lambda ws: fx.study(ws, name="s"),
     args=lambda ws: ["run", ws.path("configs", "s.yaml"), "--out", "/dev/null/x", "--quiet"], names=r"/dev/null")
case(kind, "--out a symlink loop", setup=lambda ws: (fx.study(ws, name="s"), os.symlink("loop", ws.path("loop"))),
     args=lambda ws: ["run", ws.path("configs", "s.yaml"), "--out", ws.path("loop"), "--quiet"], names=r"loop")
case(kind, "--parts unknown", setup=lambda ws: fx.study(ws, name="s"),
     args=lambda ws: ["run", ws.path("configs", "s.yaml"), "--out", ws.out, "--parts", "nope", "--quiet"],
     names=r"nope")
case(kind, "--backend unknown", setup=lambda ws: fx.study(ws, name="s"),
     args=lambda ws: ["run", ws.path("configs", "s.yaml"), "--out", ws.out, "--backend", "nope", "--quiet"],
     names=r"nope")
case(kind, "status --results missing", args=["status", "--results", "/nonexistent/results"],
     names=r"nonexistent", expect="error")
