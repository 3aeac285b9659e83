"""tools/gen-captures [--check] [--out DIR] [NAME...]

Writes every registered capture to captures/ (or DIR). With --check, writes
nothing and fails if a committed capture differs from what the code makes.
"""
import argparse
import importlib
import pkgutil
import sys
from pathlib import Path

from . import registry

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
SKIP = {"__main__", "registry", "pcap", "frames"}


def load_scenarios():
    for mod in sorted(m.name for m in pkgutil.iter_modules([str(HERE)])):
        if mod not in SKIP:
            importlib.import_module("tools.capgen." + mod)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="tools/gen-captures", description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare with the committed captures")
    ap.add_argument("--out", default=str(ROOT / "captures"), help="output folder")
    ap.add_argument("--list", action="store_true", help="list captures with their descriptions")
    ap.add_argument("names", nargs="*", help="only these captures")
    args = ap.parse_args(argv)
    load_scenarios()
    names = args.names or sorted(registry.CAPTURES)
    if args.list:
        for name in names:
            print("%-40s %s" % (name, registry.CAPTURES[name].description))
        return 0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    bad = []
    for name in names:
        data = registry.CAPTURES[name]().to_bytes()
        path = out / name
        if args.check:
            if not path.exists() or path.read_bytes() != data:
                bad.append(name)
        else:
            path.write_bytes(data)
    if bad:
        print("captures differ from their generator: " + ", ".join(bad), file=sys.stderr)
        return 1
    if not args.check:
        print("wrote %d captures to %s" % (len(names), out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
