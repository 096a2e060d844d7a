"""``jointbench data fetch NAME``: download a recorded data set (a pinned commit, its SHA-256 checked) into the user's
data folder (:func:`jointbench.api.fetch_data`)."""
from __future__ import annotations


def _fetch(args) -> int:
    from jointbench import api

    path = api.fetch_data(args.name, url=args.url)
    print(f"{args.name}: {path}")
    return 0


def add_parsers(sub) -> None:
    from jointbench.fitting.fetch import DATA_ENV, DATASETS

    p = sub.add_parser("data", help="recorded data sets fetched on demand (never shipped in the package)")
    dsub = p.add_subparsers(dest="action", required=True, parser_class=type(p))
    f = dsub.add_parser("fetch", help=f"download a data set, check its SHA-256, store it in ${DATA_ENV} "
                                      f"(default ~/.cache/jointbench)")
    f.add_argument("name", choices=sorted(DATASETS),
                   help="; ".join(f"{d.name}: {d.description}, {d.licence}" for d in DATASETS.values()))
    f.add_argument("--url", metavar="URL", help="another address of the same file (a mirror, file://...); the "
                                                "pinned SHA-256 is checked whatever the address")
    f.set_defaults(func=_fetch)
