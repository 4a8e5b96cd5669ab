#!/usr/bin/env python3
"""Every metric the Grafana dashboard and the alert rules name is one the server exports.

usage: observability_names_check.py EXPOSITION_FILE DASHBOARD_JSON ALERTS_YAML [PROMTOOL]
EXPOSITION_FILE is a real server's /metrics. A family counts as exported when the
exposition declares it (# TYPE), histograms with their _bucket, _sum and _count series.
Prometheus' own `up` is the one name no server exports. With PROMTOOL, the dashboard's
expressions (Grafana's variables replaced) are also parsed, as recording rules.
"""
import json
import re
import subprocess
import sys
import tempfile

import yaml

# What PromQL names that is not a metric: functions, aggregations, keywords.
PROMQL_WORDS = {
    "sum", "min", "max", "avg", "count", "stddev", "stdvar", "topk", "bottomk", "quantile",
    "count_values", "group", "by", "without", "on", "ignoring", "group_left", "group_right",
    "and", "or", "unless", "bool", "offset", "rate", "irate", "increase", "delta", "idelta",
    "deriv", "histogram_quantile", "abs", "ceil", "floor", "round", "clamp_min", "clamp_max",
    "label_replace", "label_join", "vector", "scalar", "time", "absent", "changes", "resets",
    "avg_over_time", "max_over_time", "min_over_time", "sum_over_time", "predict_linear",
    "humanize", "inf", "nan",
}
NOT_EXPORTED = {"up"}  # written by Prometheus for every target


def metric_names(expr):
    """The metric names in a PromQL expression: identifiers outside label matchers,
    grouping lists, ranges and strings, less PromQL's own words."""
    e = re.sub(r'"(?:\\.|[^"\\])*"', '""', expr)            # strings
    e = re.sub(r"\{[^}]*\}", "", e)                         # label matchers
    e = re.sub(r"\[[^\]]*\]", "", e)                        # ranges
    e = re.sub(r"\b(by|without|on|ignoring|group_left|group_right)\s*\([^)]*\)", "", e)
    e = re.sub(r"\$\{?\w+\}?", "", e)                       # Grafana variables
    words = re.findall(r"(?<![\w.])[a-zA-Z_:][a-zA-Z0-9_:]*", e)
    return {w for w in words if w not in PROMQL_WORDS}


def exported(exposition):
    names = set()
    for m in re.finditer(r"^# TYPE (\S+) (\S+)$", exposition, re.M):
        name, kind = m.groups()
        names.add(name)
        if kind in ("histogram", "summary"):
            names |= {name + "_bucket", name + "_sum", name + "_count"}
    return names


def dashboard_exprs(dashboard):
    out = []
    def walk(panels):
        for p in panels:
            for t in p.get("targets", []):
                out.append((p["title"], t["expr"]))
            walk(p.get("panels", []))
    walk(dashboard["panels"])
    for v in dashboard.get("templating", {}).get("list", []):
        if v.get("type") == "query":
            q = v["query"]["query"] if isinstance(v["query"], dict) else v["query"]
            inner = re.fullmatch(r"label_values\((.*),\s*\w+\)", q)
            out.append((f"variable {v['name']}", inner.group(1) if inner else q))
    return out


def main():
    exposition = open(sys.argv[1]).read()
    dashboard = json.load(open(sys.argv[2]))
    alerts = yaml.safe_load(open(sys.argv[3]))
    have = exported(exposition)
    problems, used = [], set()
    exprs = dashboard_exprs(dashboard)
    if not exprs:
        problems.append("the dashboard has no queries")
    for group in alerts["groups"]:
        for rule in group["rules"]:
            exprs.append((f"alert {rule['alert']}", rule["expr"]))
    for where, expr in exprs:
        names = metric_names(expr)
        if not names:
            problems.append(f"{where}: no metric in {expr!r}")
        for name in sorted(names - have - NOT_EXPORTED):
            problems.append(f"{where}: {name} is not on the server's /metrics")
        used |= names
    if len(sys.argv) > 4:
        # Grafana's variables as Prometheus would see them after substitution.
        rules = [{"record": f"dashboard:query:{i}",
                  "expr": expr.replace("$__rate_interval", "1m").replace("$job", ".*")
                              .replace("$instance", ".*")}
                 for i, (_, expr) in enumerate(exprs)]
        with tempfile.NamedTemporaryFile("w", suffix=".yaml") as f:
            yaml.safe_dump({"groups": [{"name": "dashboard", "rules": rules}]}, f)
            f.flush()
            done = subprocess.run([sys.argv[4], "check", "rules", f.name], capture_output=True,
                                  text=True)
            if done.returncode != 0:
                problems.append("promtool cannot parse the queries:\n" + done.stdout + done.stderr)
    print(f"observability: {len(exprs)} queries name {len(used)} metrics: "
          + ", ".join(sorted(used)))
    for p in problems:
        print("observability: FAILED:", p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
