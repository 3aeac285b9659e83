"""The JSON report (schema in docs/report.md): the model's dicts without plot series."""
import json

SCHEMA_VERSION = 1


def document(reports, fail_on, status, expect=()):
    captures = []
    for rep in reports:
        rep = dict(rep)
        rep["devices"] = [{k: v for k, v in d.items() if k != "series"} for d in rep["devices"]]
        rep.setdefault("missing", [])
        captures.append(rep)
    return {"schema": SCHEMA_VERSION, "fail_on": fail_on, "expect": list(expect),
            "exit_status": status, "captures": captures}


def write(reports, out, fail_on, status, expect=()):
    json.dump(document(reports, fail_on, status, expect), out, indent=1)
    out.write("\n")
