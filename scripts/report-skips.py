#!/usr/bin/env python3
"""Lists every test that did not run, with its reason, after scripts/test.sh's ctest run.

ctest sees a script test that exits with its SKIP_RETURN_CODE as skipped, but a gtest binary
whose cases call GTEST_SKIP() still exits 0 and passes. So both are read back:
  RESULTS/ctest.xml    ctest --output-junit: tests not run (skipped, or missing executable)
  RESULTS/gtest/*.xml  GTEST_OUTPUT=xml:RESULTS/gtest/: every gtest case with result="skipped"
With --fail (scripts/test.sh passes it when CI=true) any of them is an error: CI expects
every test to run, and a skip there means the runner lacks something the test needs.
SKINSERVE_MAY_SKIP (comma-separated ctest names, or "binary: Suite.Case" names as printed)
lists skips a runner is known and allowed to have; they are printed but do not fail.

usage: report-skips.py RESULTS [--fail]
"""
import glob
import os
import sys
import xml.etree.ElementTree as ET


def ctest_not_run(path):
    if not os.path.exists(path):
        return [("ctest", f"{path} was not written: ctest did not finish")]
    found = []
    for case in ET.parse(path).getroot().iter("testcase"):
        if case.get("status") == "run" or case.get("status") == "fail":
            continue
        out = (case.findtext("system-out") or "").strip().splitlines()
        skipped = case.find("skipped")
        why = skipped.get("message", "") if skipped is not None else case.get("status", "")
        last = out[-1] if out else "no output"
        found.append((case.get("name"), f"{why}: {last}"))
    return found


def gtest_skipped(folder):
    found = []
    for path in sorted(glob.glob(os.path.join(folder, "*.xml"))):
        binary = os.path.splitext(os.path.basename(path))[0]
        for case in ET.parse(path).getroot().iter("testcase"):
            if case.get("result") != "skipped":
                continue
            skipped = case.find("skipped")
            message = skipped.get("message", "") if skipped is not None else ""
            # "file:line\nreason": the reason is what a reader needs.
            reason = message.splitlines()[-1] if message else "no reason given"
            found.append((f"{binary}: {case.get('classname')}.{case.get('name')}", reason))
    return found


def main():
    if len(sys.argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    results = sys.argv[1]
    fail = "--fail" in sys.argv[2:]
    skips = ctest_not_run(os.path.join(results, "ctest.xml"))
    skips += gtest_skipped(os.path.join(results, "gtest"))
    if not skips:
        print("every test ran: none skipped")
        return 0
    allowed = {n.strip() for n in os.environ.get("SKINSERVE_MAY_SKIP", "").split(",") if n.strip()}
    print(f"{len(skips)} test(s) did not run:")
    for name, why in skips:
        print(f"  {name}: {why}{' (allowed by SKINSERVE_MAY_SKIP)' if name in allowed else ''}")
    if fail and any(name not in allowed for name, _ in skips):
        print("error: CI expects every test to run; make the runner provide what the tests "
              "above need (their reasons say what)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
