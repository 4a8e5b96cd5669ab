#!/usr/bin/env python3
"""Generates the tables of the docs (and of README.md) from the raw results in docs/results/.

A page asks for a table with two markers; everything between them is rewritten:

    <!-- table: results/2026-11-24-simd-vs-sse-vm/simd.csv -->
    ... (generated) ...
    <!-- end table -->

The path is relative to docs/ (also in README.md); a data file may be compressed (NAME.xz,
NAME.gz: read as it is). Options may follow the path:
    columns=0,2-4     only these columns of a CSV (0-based; ranges allowed)
    rows=0-3          only these data rows of a CSV (0-based; ranges allowed)
    view=figure5      a Google Benchmark JSON of skinserve-bench --paper-tables (M vertices/s
                      per series and grid point, medians; as scripts/figure5-plot.sh prints it)
    view=chunks       the chunk sweep's console output (== chunks N, then benchmark lines)
    view=data-plane   scripts/data-plane.sh's bench.json, with the service-*.json beside it
    view=capacity     skinserve-load --capacity's console output (its "capacity:" lines)
    data=no           no "Data:" line under the table
A .csv without view= is rendered as it is: its first row is the header.

Usage:
    scripts/docs-tables.py            rewrite every page whose tables differ from their data
    scripts/docs-tables.py --check    change nothing; exit 1 if a page's table differs, a data
                                      file is missing, a results folder lacks command.txt or
                                      machine.txt or is not listed in docs/results/index.md, or
                                      a relative link of README.md is broken
    scripts/docs-tables.py --check-site SITE
                                      after `mkdocs build`: every link between pages of the
                                      built site whose #anchor names no element on its page
                                      fails (MkDocs 1.4 checks pages, not anchors)
Python 3 standard library only.
"""
import csv
import gzip
import html.parser
import json
import lzma
import os
import re
import sys
import urllib.parse

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOCS = os.path.join(ROOT, "docs")
RESULTS = os.path.join(DOCS, "results")
MARKER = re.compile(
    r"(?P<open><!-- table: (?P<spec>[^>]*?) -->\n)(?P<body>.*?)(?P<close><!-- end table -->)",
    re.S)
NUMBER = re.compile(r"^[-+]?[0-9][0-9,]*(\.[0-9]+)?(x|%| ms| us)?$")


class TableError(Exception):
    pass


def open_text(path):
    """A data file as text; a large one may be kept compressed (NAME.xz or NAME.gz)."""
    if path.endswith(".xz"):
        return lzma.open(path, "rt", encoding="utf-8", newline="")
    if path.endswith(".gz"):
        return gzip.open(path, "rt", encoding="utf-8", newline="")
    return open(path, encoding="utf-8", newline="")


def parse_indexes(text):
    out = []
    for part in text.split(","):
        if "-" in part:
            a, b = part.split("-", 1)
            out.extend(range(int(a), int(b) + 1))
        else:
            out.append(int(part))
    return out


def parse_spec(spec):
    words = spec.split()
    if not words:
        raise TableError("a table marker names no data file")
    options = {}
    for word in words[1:]:
        if "=" not in word:
            raise TableError(f"option '{word}' is not NAME=VALUE")
        key, value = word.split("=", 1)
        if key not in ("columns", "rows", "view", "data"):
            raise TableError(f"unknown option '{key}'")
        options[key] = value
    return words[0], options


def cell(text):
    return str(text).replace("|", "\\|").replace("\n", " ")


def markdown_table(header, rows, right=None):
    if right is None:
        right = [i > 0 and all(NUMBER.match(r[i].strip()) for r in rows if i < len(r) and
                               r[i].strip()) and any(i < len(r) and r[i].strip() for r in rows)
                 for i in range(len(header))]
    lines = ["| " + " | ".join(cell(h) for h in header) + " |",
             "|" + "|".join(" ---: " if r else " --- " for r in right) + "|"]
    for row in rows:
        row = list(row) + [""] * (len(header) - len(row))
        lines.append("| " + " | ".join(cell(c) for c in row) + " |")
    return lines


def csv_view(path, options):
    with open_text(path) as f:
        table = [row for row in csv.reader(f) if row and not row[0].startswith("#")]
    if not table:
        raise TableError(f"{path} is empty")
    header, rows = table[0], table[1:]
    for n, row in enumerate(rows):
        if len(row) != len(header):
            raise TableError(f"{path}: data row {n} has {len(row)} cells, the header {len(header)}")
    if "rows" in options:
        rows = [rows[i] for i in parse_indexes(options["rows"])]
    if "columns" in options:
        cols = parse_indexes(options["columns"])
        header = [header[i] for i in cols]
        rows = [[row[i] for i in cols] for row in rows]
    return markdown_table(header, rows)


def figure5_view(path, options):
    """M vertices/s per series and (vertices, bones), medians, as scripts/figure5-plot.sh."""
    with open_text(path) as f:
        data = json.load(f)
    rates = {}  # (series, vertices, bones) -> M vertices/s
    series = []
    points = set()
    bounds = {}
    for b in data["benchmarks"]:
        if b.get("run_type") != "aggregate":
            continue
        name = b["run_name"].split("/")
        if b.get("aggregate_name") == "max" and name[0] in (
                "BM_PcieHostToDevice", "BM_PcieDeviceToHost", "BM_DeviceMemoryCopy"):
            bounds[name[0]] = b["bytes_per_second"]
        if b.get("aggregate_name") != "median":
            continue
        found = []
        if name[0] == "BM_Skin":
            found.append((name[1], b["vertices_per_second"]))
            if "kernel_vertices_per_second" in b:
                found.append((name[1] + " kernel only", b["kernel_vertices_per_second"]))
        elif name[0] == "BM_SkinStreams":
            found.append((name[1] + " x4 streams", b["items_per_second"]))
        elif name[0] == "BM_SkinDeviceOutput":
            found.append((name[1] + " output on the GPU", b["vertices_per_second"]))
        elif name[0] == "BM_SkinDeviceOutputInPlace":
            found.append((name[1] + " output on the GPU, in place", b["vertices_per_second"]))
        for s, value in found:
            if s not in series:
                series.append(s)
            point = (int(name[2]), int(name[3]))
            points.add(point)
            rates[(s, point)] = value / 1e6
    order = sorted(points, key=lambda p: (p[1], p[0]))
    header = ["M vertices/s"] + [f"{v // 1000}k x {b}" for v, b in order]
    rows = []
    for s in series:
        row = [s]
        for p in order:
            row.append(format(rates[(s, p)], ".0f") if (s, p) in rates else "-")
        rows.append(row)
    lines = markdown_table(header, rows, right=[False] + [True] * len(order))
    if bounds:
        lines += ["", "Bounds measured in the same run (best of 3): PCIe host to device "
                  f"{bounds.get('BM_PcieHostToDevice', 0) / 1e9:.1f} GB/s, device to host "
                  f"{bounds.get('BM_PcieDeviceToHost', 0) / 1e9:.1f} GB/s (pinned); device memory "
                  f"copy {bounds.get('BM_DeviceMemoryCopy', 0) / 1e9:.0f} GB/s (read + write)."]
    return lines


def rate(token):
    m = re.match(r"^([0-9.]+)([kMG]?)/s$", token)
    if not m:
        raise TableError(f"'{token}' is not a rate")
    return float(m.group(1)) * {"": 1, "k": 1e3, "M": 1e6, "G": 1e9}[m.group(2)]


def chunks_view(path, options):
    """items_per_second (M vertices/s) of each benchmark per chunk count."""
    labels = {"BM_Skin": "one stream", "BM_SkinNormals": "one stream, normals",
              "BM_SkinStreams": "4 streams"}
    chunks = []
    values = {}
    names = []
    current = None
    with open_text(path) as f:
        for line in f:
            m = re.match(r"^== chunks (\d+)", line)
            if m:
                current = int(m.group(1))
                chunks.append(current)
                continue
            words = line.split()
            if not words or current is None or not words[0].endswith("_median"):
                continue
            parts = words[0].split("/")
            if parts[0] not in labels:
                continue
            key = (parts[0], int(parts[2]), int(parts[3]))
            rates = [w for w in words if w.endswith("/s")]
            if key not in names:
                names.append(key)
            values[(key, current)] = rate(rates[1]) / 1e6  # items_per_second
    header = ["M vertices/s, chunks"] + [str(c) for c in chunks]
    rows = []
    for key in names:
        v = key[1]
        size = f"{v / 1e6:g}M" if v >= 1_000_000 else f"{v // 1000}k"
        row = [f"{size} x {key[2]}, {labels[key[0]]}"]
        row += [format(values[(key, c)], ".0f") if (key, c) in values else "-" for c in chunks]
        rows.append(row)
    return markdown_table(header, rows, right=[False] + [True] * len(chunks))


def data_plane_view(path, options):
    """scripts/data-plane.sh's run: its bench.json (the engine alone, medians) beside the
    load client's service-<vertices>.json (both data planes), in M vertices/s and as the
    engine's share."""
    with open_text(path) as f:
        bench = json.load(f)
    folder = os.path.dirname(path)
    engine = {}  # (backend, vertices) -> vertices/s
    for b in bench["benchmarks"]:
        name = b["run_name"].split("/")
        if name[0] == "BM_Skin" and b.get("aggregate_name") == "median":
            engine[(name[1], int(name[2]))] = (b["vertices_per_second"], name[3])
    rows = []
    for (backend, vertices), (alone, bones) in sorted(engine.items(), key=lambda kv: kv[0][1]):
        service = os.path.join(folder, f"service-{vertices}.json")
        if not os.path.isfile(service):
            raise TableError(f"{os.path.relpath(service, DOCS)} does not exist")
        with open_text(service) as f:
            results = json.load(f)["results"]
        planes = {r.get("data_plane", "grpc"): r["vertices_per_second"] for r in results
                  if r["backend"] == backend}
        row = [backend, f"{vertices // 1000}k x {bones}", f"{alone / 1e6:.0f}"]
        for plane in ("grpc", "shm"):
            if plane not in planes:
                raise TableError(f"{os.path.relpath(service, DOCS)}: no {plane} row")
            row += [f"{planes[plane] / 1e6:.0f}", f"{100 * planes[plane] / alone:.0f}%"]
        rows.append(row)
    header = ["backend", "frame", "engine alone M/s", "gRPC M/s", "gRPC share",
              "shared memory M/s", "shared memory share"]
    return markdown_table(header, rows)


def capacity_view(path, options):
    """skinserve-load --capacity's console output: characters held per mode and data plane
    (ticks: the mode says "ticks of N", the rate is ticks/s)."""
    held = []
    pattern = re.compile(r"^capacity: (\d+) characters \((\d+) streams x "
                         r"(?:(\d+) characters a tick x )?(\d+) instances, "
                         r"([0-9.]+) (?:fps|ticks/s), ([^,]+), ([^,)]+)")
    with open_text(path) as f:
        for line in f:
            m = pattern.match(line)
            if m:
                mode = m.group(7)
                plane = "shared memory" if mode.endswith("+shm") else "gRPC"
                mode = mode.removesuffix("+shm")
                if m.group(3):
                    mode += f", ticks of {m.group(3)}"
                held.append([m.group(6), mode, plane, m.group(5), m.group(1)])
    if not held:
        raise TableError(f"{path}: no 'capacity:' lines")
    return markdown_table(["backend", "mode", "data plane", "fps", "characters held"], held)


VIEWS = {"figure5": figure5_view, "chunks": chunks_view, "data-plane": data_plane_view,
         "capacity": capacity_view}


def render(page, spec):
    rel, options = parse_spec(spec)
    path = os.path.normpath(os.path.join(DOCS, rel))
    if not os.path.isfile(path):
        raise TableError(f"data file {rel} (docs/{rel}) does not exist")
    view = options.get("view")
    if view is None:
        if not re.sub(r"\.(xz|gz)$", "", path).endswith(".csv"):
            raise TableError(f"{rel}: only .csv files render without view=")
        lines = csv_view(path, options)
    elif view in VIEWS:
        lines = VIEWS[view](path, options)
    else:
        raise TableError(f"unknown view '{view}'")
    if options.get("data", "yes") != "no":
        folder = os.path.dirname(path)
        here = os.path.dirname(page)
        links = [f"[`{os.path.relpath(path, RESULTS)}`]({os.path.relpath(path, here)})"]
        for extra in ("command.txt", "machine.txt", "SOURCE.md"):
            if os.path.isfile(os.path.join(folder, extra)):
                links.append(f"[{extra.split('.')[0].lower()}]"
                             f"({os.path.relpath(os.path.join(folder, extra), here)})")
        lines += ["", "Data: " + " · ".join(links)]
    return "\n".join(lines) + "\n"


def pages():
    yield os.path.join(ROOT, "README.md")
    for base, dirs, files in os.walk(DOCS):
        dirs.sort()
        for name in sorted(files):
            if name.endswith(".md"):
                yield os.path.join(base, name)


def check_folders():
    problems = []
    if not os.path.isdir(RESULTS):
        return problems
    index = os.path.join(RESULTS, "index.md")
    listed = open(index, encoding="utf-8").read() if os.path.isfile(index) else ""
    for name in sorted(os.listdir(RESULTS)):
        folder = os.path.join(RESULTS, name)
        if not os.path.isdir(folder):
            continue
        if f"({name}/SOURCE.md)" not in listed:
            problems.append(f"docs/results/{name} is not listed in docs/results/index.md")
        for required in ("command.txt", "machine.txt"):
            if not os.path.isfile(os.path.join(folder, required)):
                problems.append(f"docs/results/{name} has no {required}")
    return problems


def check_readme_links():
    """README.md is not part of the site, so MkDocs does not check its links: here, every
    relative link must name a file or folder of the repository."""
    problems = []
    with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as f:
        text = f.read()
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"^[a-z]+:", target) or target.startswith("#"):
            continue
        path = target.split("#", 1)[0]
        if not os.path.exists(os.path.join(ROOT, path)):
            problems.append(f"README.md: link {target}: no such file")
    return problems


def run(check):
    stale, problems = [], check_folders() + check_readme_links()
    for page in pages():
        with open(page, encoding="utf-8") as f:
            text = f.read()

        def replace(m):
            try:
                body = render(page, m.group("spec"))
            except (TableError, OSError, ValueError, KeyError, IndexError) as e:
                problems.append(f"{os.path.relpath(page, ROOT)}: {e}")
                return m.group(0)
            return m.group("open") + body + m.group("close")

        new = MARKER.sub(replace, text)
        if new != text:
            stale.append(os.path.relpath(page, ROOT))
            if not check:
                with open(page, "w", encoding="utf-8") as f:
                    f.write(new)
    for p in problems:
        print(f"docs-tables: {p}", file=sys.stderr)
    if check and stale:
        for p in stale:
            print(f"docs-tables: {p}: a table differs from its data "
                  "(run scripts/docs-tables.py to regenerate it)", file=sys.stderr)
        return 1
    if not check:
        for p in stale:
            print(f"docs-tables: rewrote {p}")
    return 1 if problems else 0


class Anchors(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids, self.links = set(), []

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if attrs.get("id"):
            self.ids.add(attrs["id"])
        if tag == "a" and attrs.get("href"):
            self.links.append(attrs["href"])


def check_site(site):
    parsed = {}
    for base, _, files in os.walk(site):
        for name in files:
            if name.endswith(".html"):
                path = os.path.join(base, name)
                p = Anchors()
                with open_text(path) as f:
                    p.feed(f.read())
                parsed[os.path.normpath(path)] = p
    bad = []
    for path, p in sorted(parsed.items()):
        for href in p.links:
            url = urllib.parse.urlparse(href)
            if url.scheme or url.netloc or not url.fragment:
                continue
            target = path if not url.path else os.path.normpath(
                os.path.join(os.path.dirname(path), urllib.parse.unquote(url.path)))
            if os.path.isdir(target):
                target = os.path.join(target, "index.html")
            if target not in parsed:
                continue  # a data file, or a page MkDocs already checked
            if url.fragment not in parsed[target].ids:
                bad.append(f"{os.path.relpath(path, site)}: link {href}: no such anchor")
    for b in sorted(set(bad)):
        print(f"docs-tables: {b}", file=sys.stderr)
    return 1 if bad else 0


def main(argv):
    if len(argv) == 2 and argv[1] == "--check-site":
        print("usage: docs-tables.py --check-site SITE_DIR", file=sys.stderr)
        return 2
    if len(argv) == 3 and argv[1] == "--check-site":
        return check_site(argv[2])
    if len(argv) > 2 or (len(argv) == 2 and argv[1] != "--check"):
        print(__doc__, file=sys.stderr)
        return 2
    return run(check=len(argv) == 2)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
