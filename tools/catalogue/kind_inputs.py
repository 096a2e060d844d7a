"""Recordings for ``jointbench estimate``: hostile files (zip bombs, devices, FIFOs, huge CSVs), corrupt .mat
files, ensembles the wrong way round."""
from __future__ import annotations

import os
import zipfile

import numpy as np

from tools.catalogue import fixtures as fx
from tools.catalogue.core import case


def _est(name, *more, estimator="ibk_spectral"):
    return lambda ws: ["estimate", "-e", estimator, "-i", ws.path(name), "-o", ws.path("est.csv"), *more]


def _zip_bomb(ws):
    """Members of 2 GiB of zeros each (a few MB compressed), written without holding them in memory."""
    from numpy.lib import format as npf

    p = ws.path("bomb.npz")
    n = (2 << 30) // 8
    with zipfile.ZipFile(p, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        for name in ("angle", "torque"):
            with zf.open(f"{name}.npy", "w", force_zip64=True) as f:
                npf.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False, "shape": (n,)})
                block = bytes(8 << 20)
                for _ in range((2 << 30) // len(block)):
                    f.write(block)
    return p


def _mat73(ws, body: bytes, name="rec.mat"):
    p = ws.path(name)
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    p.write_bytes(header.ljust(512, b" ") + body)
    return p


def _write(name, data: bytes):
    return lambda ws: ws.path(name).write_bytes(data)


def _npz(name, **arrays):
    return lambda ws: np.savez(ws.path(name), **arrays)


kind = "inputs"
case(kind, "zip-bomb NPZ (members of 2 GiB of zeros)", setup=_zip_bomb, args=_est("bomb.npz"), timeout=180,
     names=r"bomb\.npz.*(GiB|large|compress|limit|samples)")
case(kind, "NPZ symlink to /dev/zero", timeout=40, setup=lambda ws: os.symlink("/dev/zero", ws.path("z.npz")),
     args=_est("z.npz"), names=r"z\.npz.*(regular|not a file|device)")
case(kind, "CSV symlink to /dev/zero", timeout=40, setup=lambda ws: os.symlink("/dev/zero", ws.path("z.csv")),
     args=_est("z.csv"), names=r"z\.csv.*(regular|not a file|device)")
case(kind, "MAT symlink to /dev/zero", timeout=40, setup=lambda ws: os.symlink("/dev/zero", ws.path("z.mat")),
     args=_est("z.mat"), names=r"z\.mat.*(regular|not a file|device)")
case(kind, "CSV is a FIFO", timeout=40, setup=lambda ws: os.mkfifo(ws.path("f.csv")), args=_est("f.csv"),
     names=r"f\.csv.*(regular|not a file|FIFO|pipe)")
case(kind, "NPZ is a FIFO", timeout=40, setup=lambda ws: os.mkfifo(ws.path("f.npz")), args=_est("f.npz"),
     names=r"f\.npz.*(regular|not a file|FIFO|pipe)")


def _big_csv(ws):
    p = ws.path("big.csv")
    with open(p, "w") as f:
        f.write("time,angle,torque\n")
        block = 1_000_000
        for i in range(10):
            t = np.arange(i * block, (i + 1) * block) / 1000.0
            f.write("".join(f"{x:.3f},0.01,0.5\n" for x in t))
    return p


case(kind, "CSV of 10^7 rows", setup=_big_csv, args=_est("big.csv"), timeout=120,
     names=r"big\.csv.*(rows|samples|large|limit|MB)")
case(kind, "corrupt HDF5 .mat", setup=lambda ws: _mat73(ws, b"\x89HDF\r\n\x1a\n" + os.urandom(3000)),
     args=_est("rec.mat"), names=r"rec\.mat")
case(kind, "HDF5 .mat of random bytes", setup=lambda ws: _mat73(ws, os.urandom(4000)), args=_est("rec.mat"),
     names=r"rec\.mat")


def _truncated_h5(ws):
    import h5py

    p = ws.path("full.mat")
    with h5py.File(p, "w", userblock_size=512) as f:
        f["angle"] = np.zeros(1000)
        f["torque"] = np.zeros(1000)
    data = p.read_bytes()
    ws.path("rec.mat").write_bytes(data[: len(data) // 2])


case(kind, "truncated HDF5 .mat", setup=_truncated_h5, args=_est("rec.mat"), names=r"rec\.mat")
case(kind, "v5 .mat truncated", args=_est("rec.mat"), names=r"rec\.mat",
     setup=lambda ws: (__import__("scipy.io").io.savemat(ws.path("full.mat"), {"angle": np.zeros(500), "torque": np.zeros(500),
                                                                                "fs": 500.0}),
                       ws.path("rec.mat").write_bytes(ws.path("full.mat").read_bytes()[:300])))
case(kind, "NPZ not a zip", setup=_write("x.npz", b"PK\x03\x04garbage" * 10), args=_est("x.npz"), names=r"x\.npz")
case(kind, "NPZ of pickled objects", args=_est("o.npz"), names=r"o\.npz",
     setup=lambda ws: np.savez(ws.path("o.npz"), angle=np.array([{"a": 1}] * 10, dtype=object),
                               torque=np.zeros(10), fs=500.0))
case(kind, "NPZ header claims 10^12 samples", args=_est("h.npz"), names=r"h\.npz",
     setup=lambda ws: _fake_header(ws, "h.npz", (10 ** 12,)))


def _fake_header(ws, name, shape):
    from numpy.lib import format as npf
    with zipfile.ZipFile(ws.path(name), "w") as zf:
        for member in ("angle", "torque"):
            with zf.open(f"{member}.npy", "w") as f:
                npf.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False, "shape": shape})
                f.write(bytes(800))


case(kind, "CSV latin-1", args=_est("l.csv"), names=r"l\.csv",
     setup=_write("l.csv", "# Müller\ntime,angle,torque\n0,0,0\n0.002,0.1,1\n".encode("latin-1")))
case(kind, "CSV UTF-16", args=_est("u.csv"), names=r"u\.csv",
     setup=_write("u.csv", "time,angle,torque\n0,0,0\n0.002,0.1,1\n".encode("utf-16")))
def _nan_csv(ws):
    lines = fx.recording_csv(ws.path("r.csv")).read_text().splitlines()
    t, a, _ = lines[100].split(",")
    lines[100] = f"{t},{a},nan"
    ws.path("n.csv").write_text("\n".join(lines) + "\n")


case(kind, "CSV with NaN", args=_est("n.csv"), names=r"n\.csv.*(NaN|finite)", setup=_nan_csv)
case(kind, "CSV 50 MB of one line", args=_est("w.csv"), timeout=90, names=r"w\.csv",
     setup=_write("w.csv", b"time,angle,torque\n" + b"1" * 50_000_000 + b"\n"))
case(kind, "--output is the input", setup=lambda ws: fx.recording_csv(ws.path("rec.csv")),
     args=lambda ws: ["estimate", "-e", "ibk_spectral", "-i", ws.path("rec.csv"), "-o", ws.path("rec.csv")],
     names=r"overwrite input")
case(kind, "--output in a read-only folder", needs=fx.need_unshare, names=r"ro",
     setup=lambda ws: (fx.recording_csv(ws.path("rec.csv")), ws.path("ro").mkdir()),
     args=lambda ws: ["estimate", "-e", "ibk_spectral", "-i", ws.path("rec.csv"), "-o", ws.path("ro", "e.csv")],
     prefix=lambda ws: fx.readonly_prefix(ws.path("ro")))
# ensembles the wrong way round (the estimator side of issue 20; kept here as a measure)
case(kind, "ensemble transposed (realizations x samples)", args=_est("e.npz", estimator="ensemble_irf"),
     names=r"e\.npz.*(transpos|realizations|samples)",
     setup=lambda ws: fx.ensemble_npz(ws.path("e.npz"), transpose=True, realizations=40, samples=600))
case(kind, "ensemble time in ms", args=_est("e.npz", estimator="ensemble_irf"), names=r"e\.npz|lag|ms|sample",
     setup=lambda ws: fx.ensemble_npz(ws.path("e.npz"), time_scale=1000.0))
case(kind, "ensemble of 12 samples", args=_est("e.npz", estimator="ensemble_irf"), names=r"e\.npz|samples|short",
     setup=lambda ws: fx.ensemble_npz(ws.path("e.npz"), samples=12, realizations=30))
case(kind, "guarin on time in ms", args=_est("e.npz", estimator="guarin"), names=r"e\.npz|lag|ms|sample",
     setup=lambda ws: fx.ensemble_npz(ws.path("e.npz"), time_scale=1000.0))
