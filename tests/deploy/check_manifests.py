#!/usr/bin/env python3
"""Checks that the deployment files agree with each other and with the project.

yamllint checks the syntax and style; this renders every kustomize overlay under
deploy/k8s/overlays/ (`kubectl kustomize`, offline) and checks what a cluster would only tell
us at apply time, or never: the version label everywhere equals project(VERSION), the pods have
CPU and memory limits and no thread count matched to them by hand (the server reads its
cgroup), their budgets fit the memory limit (the server's own --memory-envelope), the probes reach the health service (through skinserve-cli over the pod's Unix
socket when TCP has TLS, which the kubelet's gRPC probes cannot speak) with liveness asking
"liveness" and readiness the whole server, the TLS files come from a Secret and the
authorization policy from a ConfigMap equal to deploy/authz-policy.json, no pod mounts a
service account token, the grace period outlasts the drain, the Service, autoscaler and
disruption budget select the Deployment's pods, the NetworkPolicy admits only the scraper
to the metrics port and everyone to gRPC, and the image is built on a base pinned by
digest with no debugging tools in its runtime packages. Each overlay has its own rules on
top (PROFILES): production and gpu with mutual TLS, the policy, anti-affinity, an autoscaler
and a disruption budget; development one plaintext replica; gpu a GPU limit, the GPU pool's
node selector and toleration, and OpenCL on the GPU by default.

usage: check_manifests.py <repository root> <skinserve binary>   (kubectl from $KUBECTL, else PATH)
"""
import json
import os
import pathlib
import re
import subprocess
import sys

import yaml

failures = []


def check(condition, message):
    if not condition:
        failures.append(message)
    return condition


def cpu_cores(quantity):
    q = str(quantity)
    return float(q[:-1]) / 1000 if q.endswith("m") else float(q)


def duration_seconds(text):
    """'30s', '1m', '1500ms' or a plain number of seconds."""
    m = re.fullmatch(r"\s*([0-9.]+)\s*(ms|s|m)?\s*", str(text))
    if not m:
        raise ValueError(f"not a duration: {text!r}")
    value, unit = float(m.group(1)), m.group(2) or "s"
    return value / 1000 if unit == "ms" else value * 60 if unit == "m" else value


# What each overlay must be, beyond what every rendered server must be.
PROFILES = {
    "development": {"tls": False, "replicas": (1, 1), "autoscaled": False, "gpu": False},
    "production": {"tls": True, "replicas": (2, None), "autoscaled": True, "gpu": False},
    "gpu": {"tls": True, "replicas": (2, None), "autoscaled": True, "gpu": True},
}


def render(overlay):
    """The overlay's objects as `kubectl kustomize` renders them (no cluster needed)."""
    kubectl = os.environ.get("KUBECTL", "kubectl")
    done = subprocess.run([kubectl, "kustomize", str(overlay)], capture_output=True, text=True)
    if not check(done.returncode == 0,
                 f"{overlay.name}: kubectl kustomize failed: {done.stderr.strip()}"):
        return []
    return [d for d in yaml.safe_load_all(done.stdout) if d]


def main(root):
    root = pathlib.Path(root)
    cmake = (root / "CMakeLists.txt").read_text()
    version = re.search(r"project\(skinserve\s+VERSION\s+([0-9][0-9.]*)", cmake).group(1)

    k8s = root / "deploy" / "k8s"
    check(not list(k8s.glob("*.yaml")),
          "deploy/k8s/: manifests outside base/ and overlays/ (kubectl apply -f would mix them)")
    overlays = sorted(p for p in (k8s / "overlays").iterdir() if p.is_dir())
    check(sorted(p.name for p in overlays) == sorted(PROFILES),
          f"deploy/k8s/overlays: {[p.name for p in overlays]}, the checks know {sorted(PROFILES)}")
    for overlay in overlays:
        if overlay.name in PROFILES:
            check_overlay(root, overlay.name, render(overlay), version, PROFILES[overlay.name])

    check_repository(root, version)


def check_overlay(root, name, objects, version, profile):
    """One rendered overlay: a server Deployment, its Service and ConfigMaps, and what its
    profile asks for."""
    where = f"overlays/{name}"
    docs, config_maps = {}, {}
    for doc in objects:
        if doc["kind"] == "ConfigMap":
            config_maps[doc["metadata"]["name"]] = doc
        else:
            check(doc["kind"] not in docs, f"{where}: two {doc['kind']} objects")
            docs[doc["kind"]] = doc
        labels = doc["metadata"].get("labels", {})
        check(labels.get("app.kubernetes.io/version") == version,
              f"{where}: {doc['kind']} label app.kubernetes.io/version is "
              f"{labels.get('app.kubernetes.io/version')!r}, project is {version}")
    wanted = ["Deployment", "Service", "NetworkPolicy"]
    if profile["autoscaled"]:
        wanted += ["HorizontalPodAutoscaler", "PodDisruptionBudget"]
    for kind in wanted:
        check(kind in docs, f"{where}: no {kind}")
    check("skinserve" in config_maps, f"{where}: no ConfigMap skinserve")
    if not all(kind in docs for kind in wanted) or "skinserve" not in config_maps:
        return

    docs["ConfigMap"] = config_maps["skinserve"]
    dep = docs["Deployment"]
    pod = dep["spec"]["template"]
    pod_labels = pod["metadata"]["labels"]
    check(pod_labels.get("app.kubernetes.io/version") == version,
          f"{where}: pod template version label differs from the project version")
    check(dep["spec"]["selector"]["matchLabels"].items() <= pod_labels.items(),
          f"{where}: Deployment selector does not match its pod template")
    low, high = profile["replicas"]
    replicas = dep["spec"].get("replicas", 1)
    check(replicas >= low and (high is None or replicas <= high),
          f"{where}: {replicas} replicas, wanted {low}" + (f"..{high}" if high else " or more"))

    (container,) = pod["spec"]["containers"]
    check(container["image"].endswith(":" + version),
          f"{where}: image {container['image']} is not tagged {version}")
    refs = [e["configMapRef"]["name"] for e in container.get("envFrom", [])
            if "configMapRef" in e]
    check(docs["ConfigMap"]["metadata"]["name"] in refs,
          f"{where}: the ConfigMap is not in envFrom")
    config = effective_env(container, config_maps)
    check_regions_on_socket(where, config, same_host=False)
    check_pod_hardening(where, pod["spec"])
    ports = {p["name"]: p["containerPort"] for p in container["ports"]}
    tcp, sockets = listen_addresses(config.get("SKINSERVE_LISTEN", ""))
    if not check(tcp, f"{where}: SKINSERVE_LISTEN has no host:port address"):
        return
    listen_port = int(tcp[0].rsplit(":", 1)[1])
    check(ports.get("grpc") == listen_port,
          f"{where}: containerPort grpc {ports.get('grpc')} != SKINSERVE_LISTEN port")
    # Metrics: the port SKINSERVE_METRICS_LISTEN serves is the containerPort "metrics",
    # and the pod's scrape annotations point at it.
    if check("SKINSERVE_METRICS_LISTEN" in config, f"{where}: no SKINSERVE_METRICS_LISTEN"):
        metrics_port = int(config["SKINSERVE_METRICS_LISTEN"].rsplit(":", 1)[1])
        check(ports.get("metrics") == metrics_port,
              f"{where}: containerPort metrics {ports.get('metrics')} != "
              f"SKINSERVE_METRICS_LISTEN port {metrics_port}")
        notes = pod["metadata"].get("annotations", {})
        check(notes.get("prometheus.io/scrape") == "true" and
              notes.get("prometheus.io/port") == str(metrics_port) and
              notes.get("prometheus.io/path") == "/metrics",
              f"{where}: pod template lacks prometheus.io/scrape, port and path annotations "
              f"for port {metrics_port}")
    # Connection hygiene: connections age out (clients re-resolve and find new replicas),
    # with a grace that lets a frame finish.
    if check("SKINSERVE_MAX_CONNECTION_AGE_SECONDS" in config,
             f"{where}: no SKINSERVE_MAX_CONNECTION_AGE_SECONDS"):
        check(float(config["SKINSERVE_MAX_CONNECTION_AGE_SECONDS"]) > 0,
              f"{where}: connections never age out")
        check(float(config.get("SKINSERVE_MAX_CONNECTION_AGE_GRACE_SECONDS", 0)) >= 1,
              f"{where}: SKINSERVE_MAX_CONNECTION_AGE_GRACE_SECONDS under a second")

    check_network_policy(where, docs["NetworkPolicy"], pod_labels, ports)
    check_sizing(where, container, config)
    check_memory_envelope(where, container, config)
    tls = bool(config.get("SKINSERVE_TLS_CERT"))
    check(tls == profile["tls"],
          f"{where}: TLS on the gRPC port (SKINSERVE_TLS_CERT) is {tls}, wanted {profile['tls']}")
    if tls:
        check_tls_files(where, pod["spec"], container, config)
    if profile["tls"]:
        if check(config.get("SKINSERVE_AUTHZ_POLICY"), f"{where}: no SKINSERVE_AUTHZ_POLICY"):
            check_policy(where, root, pod["spec"], container, config, config_maps)
    check_probes(where, container, tls, listen_port, sockets)

    grace = pod["spec"].get("terminationGracePeriodSeconds", 30)
    if check("SKINSERVE_DRAIN_SECONDS" in config, f"{where}: no SKINSERVE_DRAIN_SECONDS"):
        drain = duration_seconds(config["SKINSERVE_DRAIN_SECONDS"])
        pre_stop = container.get("lifecycle", {}).get("preStop", {})
        pause = 0.0
        if "exec" in pre_stop and pre_stop["exec"]["command"][0] == "sleep":
            pause = float(pre_stop["exec"]["command"][1])
        if "sleep" in pre_stop:
            pause = float(pre_stop["sleep"]["seconds"])
        check(grace > pause + drain,
              f"{where}: terminationGracePeriodSeconds {grace} <= preStop {pause} s + "
              f"drain {drain} s")

    svc = docs["Service"]
    check(svc["spec"].get("clusterIP") == "None", f"{where}: Service not headless (clusterIP: None)")
    check(svc["spec"]["selector"].items() <= pod_labels.items(),
          f"{where}: Service selector does not match the pods")
    svc_ports = svc["spec"]["ports"]
    check(any(p.get("targetPort") in ("grpc", listen_port) for p in svc_ports),
          f"{where}: Service has no port to the grpc containerPort")

    if profile["autoscaled"]:
        check_autoscaled(where, dep, pod["spec"], pod_labels, docs)
    else:
        check("HorizontalPodAutoscaler" not in docs,
              f"{where}: an autoscaler on a single-replica overlay")
    check_gpu(where, pod["spec"], container, config, profile["gpu"])


def check_network_policy(where, policy, pod_labels, ports):
    """The metrics port (plain HTTP, no authentication) admits only the scraper's pods,
    named by labels; the gRPC port stays open to every client (issue 42)."""
    spec = policy["spec"]
    check(spec.get("podSelector", {}).get("matchLabels", {}).items() <= pod_labels.items()
          and spec.get("podSelector", {}).get("matchLabels"),
          f"{where}: NetworkPolicy does not select the server's pods")
    check("Ingress" in spec.get("policyTypes", []),
          f"{where}: NetworkPolicy has no Ingress policy type (it filters nothing coming in)")

    def admits(rule, name):
        """Whether an ingress rule covers the containerPort `name` (no ports: all of them)."""
        if "ports" not in rule:
            return True
        return any(p.get("port") in (name, ports.get(name)) for p in rule["ports"])

    rules = spec.get("ingress", [])
    to_metrics = [r for r in rules if admits(r, "metrics")]
    check(to_metrics, f"{where}: NetworkPolicy admits nobody to the metrics port (no scrapes)")
    for rule in to_metrics:
        peers = rule.get("from", [])
        check(peers and all(p.get("podSelector", {}).get("matchLabels") and "ipBlock" not in p
                            for p in peers),
              f"{where}: NetworkPolicy admits the metrics port from {peers or 'anywhere'}, not "
              "only from the scraper's pods (a podSelector with labels)")
    check(any(admits(r, "grpc") and not r.get("from") for r in rules),
          f"{where}: NetworkPolicy no longer admits every client to the gRPC port")


def check_autoscaled(where, dep, pod_spec, pod_labels, docs):
    """Autoscaler on CPU from two replicas up, a disruption budget, and replicas kept on
    different nodes where the nodes allow."""
    hpa = docs["HorizontalPodAutoscaler"]
    check(hpa["apiVersion"] == "autoscaling/v2", f"{where}: HPA not autoscaling/v2")
    check(hpa["spec"]["scaleTargetRef"]["name"] == dep["metadata"]["name"],
          f"{where}: HPA does not target the Deployment")
    check(any(m["type"] == "Resource" and m["resource"]["name"] == "cpu"
              for m in hpa["spec"]["metrics"]), f"{where}: HPA has no CPU metric")
    check(hpa["spec"]["minReplicas"] >= 2, f"{where}: HPA minReplicas below 2")

    pdb = docs["PodDisruptionBudget"]
    check(pdb["spec"]["selector"]["matchLabels"].items() <= pod_labels.items(),
          f"{where}: PDB selector does not match the pods")

    anti = pod_spec.get("affinity", {}).get("podAntiAffinity", {})
    terms = [t.get("podAffinityTerm", t) for key in (
        "requiredDuringSchedulingIgnoredDuringExecution",
        "preferredDuringSchedulingIgnoredDuringExecution") for t in anti.get(key, [])]
    check(any(t.get("topologyKey") == "kubernetes.io/hostname" and
              t.get("labelSelector", {}).get("matchLabels", {}).items() <= pod_labels.items()
              for t in terms),
          f"{where}: no pod anti-affinity on kubernetes.io/hostname selecting its own pods")


def check_gpu(where, pod_spec, container, config, gpu):
    """A GPU overlay asks for a GPU on nodes that have one and makes OpenCL on the GPU the
    default; the others ask for none."""
    limits = container.get("resources", {}).get("limits", {})
    has_gpu = "nvidia.com/gpu" in limits
    check(has_gpu == gpu, f"{where}: nvidia.com/gpu limit present is {has_gpu}, wanted {gpu}")
    if not gpu:
        return
    check(int(limits["nvidia.com/gpu"]) >= 1, f"{where}: nvidia.com/gpu limit under 1")
    check(bool(pod_spec.get("nodeSelector")), f"{where}: no nodeSelector for the GPU pool")
    check(any(t.get("key") == "nvidia.com/gpu" for t in pod_spec.get("tolerations", [])),
          f"{where}: no toleration for the GPU pool's nvidia.com/gpu taint")
    check(config.get("SKINSERVE_DEFAULT_BACKEND") == "opencl",
          f"{where}: SKINSERVE_DEFAULT_BACKEND is {config.get('SKINSERVE_DEFAULT_BACKEND')!r}, "
          "not opencl")
    check(config.get("SKINSERVE_OPENCL_DEVICE") == "gpu",
          f"{where}: SKINSERVE_OPENCL_DEVICE is not gpu (the first CPU device would be chosen)")


def memory_bytes(quantity):
    m = re.fullmatch(r"([0-9.]+)(Ki|Mi|Gi|Ti|k|M|G|T)?", str(quantity))
    scale = {None: 1, "Ki": 2**10, "Mi": 2**20, "Gi": 2**30, "Ti": 2**40, "k": 1e3, "M": 1e6,
             "G": 1e9, "T": 1e12}
    return float(m.group(1)) * scale[m.group(2)]


ENVELOPE_VARIABLES = ("SKINSERVE_MESH_BUDGET_MB", "SKINSERVE_INFLIGHT_BUDGET_MB",
                      "SKINSERVE_UPLOAD_BUDGET_MB", "SKINSERVE_SHM_BUDGET_MB",
                      "SKINSERVE_SHM_DIR", "SKINSERVE_BACKENDS")


def check_memory_envelope(where, container, env):
    """The server's own --memory-envelope under the container's memory limit and budgets:
    every budget with the copies it does not count, plus the process, fits the limit."""
    limit = container.get("resources", {}).get("limits", {}).get("memory")
    if not check(limit is not None, f"{where}: no memory limit"):
        return
    limit_mb = int(memory_bytes(limit) // 2**20)
    server_env = {k: v for k, v in os.environ.items() if not k.startswith("SKINSERVE_")}
    server_env.update({k: str(env[k]) for k in ENVELOPE_VARIABLES if k in env})
    done = subprocess.run([SERVER_BINARY, "--memory-envelope", "--memory-limit-mb", str(limit_mb)],
                          capture_output=True, text=True, env=server_env)
    check(done.returncode == 0,
          f"{where}: the budgets do not fit the memory limit {limit}:\n{done.stdout}{done.stderr}")


def check_repository(root, version):
    """The image, compose.yaml and the same-host example: one of each, outside the overlays."""
    dockerfile = (root / "deploy" / "Dockerfile").read_text()
    m = re.search(r"^ARG VERSION=(\S+)", dockerfile, re.M)
    check(m and m.group(1) == version, "Dockerfile: ARG VERSION default != project version")
    check("org.opencontainers.image.version" in dockerfile, "Dockerfile: no version label")
    check(re.search(r"^HEALTHCHECK", dockerfile, re.M) is not None, "Dockerfile: no HEALTHCHECK")
    check(re.search(r"^USER (?!0\b|root\b)", dockerfile, re.M) is not None,
          "Dockerfile: does not switch to a non-root USER")
    check_base_image(dockerfile)
    check_runtime_packages((root / "scripts" / "install-deps.sh").read_text())

    compose = yaml.safe_load((root / "deploy" / "compose.yaml").read_text())
    image = compose["services"]["server"]["image"]
    check(f":-{version}}}" in image, f"compose.yaml: default image version is not {version}")
    server_env = compose["services"]["server"].get("environment", {})
    for name in ("SKINSERVE_THREADS", "POCL_MAX_PTHREAD_COUNT"):
        check(name not in server_env,
              f"compose.yaml: {name} is set; give the server a CPU limit (cpus:) instead")
    check("cpus" in compose["services"]["server"], "compose.yaml: the server has no cpus limit")
    if check("SKINSERVE_METRICS_LISTEN" in server_env, "compose.yaml: no SKINSERVE_METRICS_LISTEN"):
        compose_metrics = server_env["SKINSERVE_METRICS_LISTEN"].rsplit(":", 1)[1]
        check(any(str(p).endswith(f":{compose_metrics}")
                  for p in compose["services"]["server"].get("ports", [])),
              f"compose.yaml: the metrics port {compose_metrics} is not published")
    load = compose["services"]["load"]
    check(load["depends_on"]["server"]["condition"] == "service_healthy",
          "compose.yaml: load does not wait for a healthy server")
    check_same_host_compose(compose)
    base_maps = {d["metadata"]["name"] for d in
                 yaml.safe_load_all((root / "deploy" / "k8s" / "base" / "configmap.yaml").read_text())
                 if d and d["kind"] == "ConfigMap"}
    for path in sorted((root / "deploy" / "k8s" / "same-host").glob("*.yaml")):
        for doc in yaml.safe_load_all(path.read_text()):
            if doc and doc["kind"] == "Deployment":
                check_same_host_pod(path.name, doc, version, base_maps)
    check_path_mentions(root)


# Where the repository names files of deploy/k8s (documentation, comments, scripts).
MENTION_DIRS = ("docs", "deploy", "scripts", "tests", ".ci")
MENTION = re.compile(r"deploy/k8s/[A-Za-z0-9_./-]*[A-Za-z0-9_-]")


def check_path_mentions(root):
    """Every deploy/k8s/... path the repository mentions exists (moved files leave none
    behind in the docs)."""
    files = [root / "README.md"]
    for d in MENTION_DIRS:
        files += [f for f in (root / d).rglob("*") if f.is_file() and f.suffix in
                  (".md", ".yaml", ".yml", ".sh", ".py", ".txt", "") and "results" not in f.parts]
    for f in files:
        try:
            text = f.read_text()
        except (UnicodeDecodeError, OSError):
            continue
        for m in MENTION.finditer(text):
            check((root / m.group(0)).exists(),
                  f"{f.relative_to(root)}: names {m.group(0)}, which does not exist")


def effective_env(container, config_maps):
    """The container's environment: its ConfigMaps (envFrom), then its own env over them."""
    env = {}
    for source in container.get("envFrom", []):
        name = source.get("configMapRef", {}).get("name")
        if name in config_maps:
            env.update(config_maps[name].get("data", {}))
    for e in container.get("env", []):
        if "value" in e:
            env[e["name"]] = e["value"]
    return env


def listen_addresses(text):
    """SKINSERVE_LISTEN's host:port addresses and unix: socket paths."""
    entries = [a for a in str(text).split(",") if a]
    return ([a for a in entries if not a.startswith("unix:")],
            [a[5:] for a in entries if a.startswith("unix:")])


def check_pod_hardening(where, pod_spec):
    check(pod_spec.get("automountServiceAccountToken") is False,
          f"{where}: automountServiceAccountToken is not false (the server never calls the "
          "Kubernetes API)")


def check_sizing(where, container, env):
    """CPU and memory limits the server reads from its cgroup, requests = limits, and no
    thread count matched to them by hand."""
    res = container.get("resources", {})
    limits, requests = res.get("limits", {}), res.get("requests", {})
    for what in ("cpu", "memory"):
        check(what in limits, f"{where}: no {what} limit (the server sizes itself to it)")
    if "cpu" in limits and "cpu" in requests:
        check(cpu_cores(requests["cpu"]) == cpu_cores(limits["cpu"]),
              f"{where}: cpu request {requests['cpu']} != limit {limits['cpu']}")
    for name in ("SKINSERVE_THREADS", "POCL_MAX_PTHREAD_COUNT"):
        check(name not in env,
              f"{where}: {name} is set; the server reads the CPU limit from its cgroup "
              "(cpu.max) and sizes its compute threads and PoCL's to it")


def mounted_volume(pod_spec, container, path):
    """The volume and mount that hold `path` in the container, or (None, None)."""
    volumes = {v["name"]: v for v in pod_spec.get("volumes", [])}
    for m in container.get("volumeMounts", []):
        if path.startswith(m["mountPath"].rstrip("/") + "/"):
            return volumes.get(m["name"]), m
    return None, None


def check_tls_files(where, pod_spec, container, env):
    for name in ("SKINSERVE_TLS_CERT", "SKINSERVE_TLS_KEY", "SKINSERVE_TLS_CLIENT_CA"):
        path = env.get(name)
        if not check(path, f"{where}: TLS without {name}"):
            continue
        volume, mount = mounted_volume(pod_spec, container, path)
        check(volume is not None and "secret" in volume and mount.get("readOnly") is True,
              f"{where}: {name} {path} is not in a read-only Secret volume")


def check_policy(where, root, pod_spec, container, env, config_maps):
    """The policy file is a key of a ConfigMap volume, and that ConfigMap holds the same
    policy as deploy/authz-policy.json (the one the tests run)."""
    path = env["SKINSERVE_AUTHZ_POLICY"]
    volume, mount = mounted_volume(pod_spec, container, path)
    name = (volume or {}).get("configMap", {}).get("name")
    if not check(name in config_maps and mount.get("readOnly") is True,
                 f"{where}: SKINSERVE_AUTHZ_POLICY {path} is not in a read-only volume of a "
                 "ConfigMap in k8s/"):
        return
    key = path.rsplit("/", 1)[1]
    data = config_maps[name].get("data", {})
    if check(key in data, f"{where}: ConfigMap {name} has no key {key}"):
        example = json.loads((root / "deploy" / "authz-policy.json").read_text())
        check(json.loads(data[key]) == example,
              f"ConfigMap {name}: {key} differs from deploy/authz-policy.json")


def probe_target(probe):
    """(kind, detail, service) of a probe: ("grpc", port, service) or ("exec", target,
    service) for `skinserve-cli ... health [--service S]`; None for anything else."""
    if "grpc" in probe:
        return "grpc", probe["grpc"].get("port"), probe["grpc"].get("service", "")
    command = [str(c) for c in probe.get("exec", {}).get("command", [])]
    if not command or command[0] != "skinserve-cli" or "health" not in command:
        return None
    target = command[command.index("--target") + 1] if "--target" in command else None
    service = command[command.index("--service") + 1] if "--service" in command else ""
    return "exec", target, service


def check_probes(where, container, tls, listen_port, sockets):
    """Readiness and startup ask the whole server (""), liveness asks "liveness" and gives
    up later than readiness. With TLS on TCP the kubelet's gRPC probes cannot connect:
    skinserve-cli over one of the server's Unix sockets instead."""
    seen = {}
    for name in ("readinessProbe", "livenessProbe", "startupProbe"):
        probe = container.get(name)
        if not check(probe is not None, f"{where}: no {name}"):
            continue
        target = probe_target(probe)
        if not check(target is not None,
                     f"{where}: {name} is neither a gRPC probe nor skinserve-cli health"):
            continue
        kind, detail, service = target
        if kind == "grpc":
            check(not tls and detail == listen_port,
                  f"{where}: {name} is a gRPC probe on port {detail}"
                  + (": the kubelet's gRPC probes speak no TLS" if tls else
                     f", not the served port {listen_port}"))
        else:
            check(str(detail).startswith("unix:") and str(detail)[5:] in sockets,
                  f"{where}: {name} asks {detail}, not one of the server's Unix sockets "
                  f"{sockets}")
        want = "liveness" if name == "livenessProbe" else ""
        check(service == want, f"{where}: {name} asks the health service {service!r}, not "
                               f"{want!r}")
        seen[name] = probe
    if "readinessProbe" in seen and "livenessProbe" in seen:
        def patience(p):
            return p.get("periodSeconds", 10) * p.get("failureThreshold", 3)
        check(patience(seen["livenessProbe"]) > patience(seen["readinessProbe"]),
              f"{where}: liveness gives up no later than readiness")


# Tools for inspecting a machine or a process, not for running skinserve.
DEBUGGING_TOOLS = {"clinfo", "gdb", "strace", "ltrace", "valgrind", "curl", "wget", "procps",
                   "iproute2", "net-tools", "tcpdump", "vim", "nano", "less", "openssl",
                   "python3", "jq"}


def check_base_image(dockerfile):
    """Every stage starts FROM the BASE_IMAGE argument, whose default is pinned by digest."""
    m = re.search(r"^ARG BASE_IMAGE=(\S+)", dockerfile, re.M)
    if check(m is not None, "Dockerfile: no ARG BASE_IMAGE"):
        check(re.search(r"@sha256:[0-9a-f]{64}$", m.group(1)) is not None,
              f"Dockerfile: BASE_IMAGE {m.group(1)} is not pinned by digest (@sha256:...)")
    for line in re.findall(r"^FROM\s+(\S+)", dockerfile, re.M):
        check(line == "${BASE_IMAGE}" or "@sha256:" in line,
              f"Dockerfile: FROM {line} is neither ${{BASE_IMAGE}} nor pinned by digest")


def check_runtime_packages(script):
    """install-deps.sh's runtime set (the image's runtime stage) holds no debugging tools."""
    runtime = []
    for m in re.finditer(r"^(?:SIMD_)?RUNTIME_PACKAGES\+?=\(([^)]*)\)", script, re.M):
        runtime += m.group(1).split()
    check(runtime, "install-deps.sh: no RUNTIME_PACKAGES")
    tools = sorted(set(runtime) & DEBUGGING_TOOLS)
    check(not tools, f"install-deps.sh: debugging tools in the runtime set: {tools}")


def flag(args, name):
    """The value of --name=VALUE in a list of arguments, or None."""
    for a in args:
        if a.startswith(f"--{name}="):
            return a.split("=", 1)[1]
    return None


def check_regions_on_socket(where, env, same_host):
    """Shared-memory region calls stay on the Unix socket (issue 42): --shm-over-tcp only
    with mutual TLS, and never in the same-host examples, whose TCP (if any) must refuse
    them. The server's default is off; the examples say so explicitly."""
    over_tcp = str(env.get("SKINSERVE_SHM_OVER_TCP", "unset" if same_host else "false")).lower()
    if same_host:
        check(over_tcp == "false",
              f"{where}: SKINSERVE_SHM_OVER_TCP is {over_tcp!r}, not an explicit false: region "
              "calls must stay on the Unix socket")
    elif over_tcp not in ("false", "0", ""):
        check(env.get("SKINSERVE_TLS_CLIENT_CA"),
              f"{where}: SKINSERVE_SHM_OVER_TCP without SKINSERVE_TLS_CLIENT_CA (mutual TLS)")


def check_same_host_client(where, args, shm_dir, socket_dir, frame_socket=None):
    """A same-host client: the shared-memory data plane in the server's --shm-dir (its
    requests on StreamSkin, or on the server's frame socket), and gRPC over the server's
    Unix socket in the shared folder."""
    planes = flag(args, "data-planes")
    check("--shared-memory" in args or planes in ("shm", "grpc,shm", "socket"),
          f"{where}: the client does not use the shared-memory data plane")
    if planes == "socket":
        check(frame_socket and flag(args, "frame-socket") == frame_socket,
              f"{where}: --frame-socket {flag(args, 'frame-socket')} is not the server's "
              f"SKINSERVE_FRAME_SOCKET {frame_socket}")
        check(frame_socket and frame_socket.rsplit("/", 1)[0] == shm_dir,
              f"{where}: the frame socket {frame_socket} is not in the shared folder {shm_dir}")
    check(flag(args, "shm-dir") == shm_dir,
          f"{where}: --shm-dir {flag(args, 'shm-dir')} is not the server's {shm_dir}")
    target = flag(args, "target") or ""
    check(target.startswith("unix:" + socket_dir + "/"),
          f"{where}: --target {target} is not the server's socket in {socket_dir}")


def check_same_host_compose(compose):
    """compose.yaml's renderer: beside the server on the shared tmpfs volume."""
    server, renderer = compose["services"]["server"], compose["services"].get("renderer")
    if not check(renderer is not None, "compose.yaml: no renderer (same-host client)"):
        return
    env = server.get("environment", {})
    shm_dir = env.get("SKINSERVE_SHM_DIR")
    sockets = [a[5:] for a in env.get("SKINSERVE_LISTEN", "").split(",") if a.startswith("unix:")]
    mounts = {v.split(":")[1]: v.split(":")[0] for v in server.get("volumes", [])}
    check(shm_dir in mounts, f"compose.yaml: the server's SKINSERVE_SHM_DIR {shm_dir} is no volume")
    check(sockets and sockets[0].rsplit("/", 1)[0] == shm_dir,
          "compose.yaml: the server has no Unix socket in its shm volume")
    renderer_mounts = {v.split(":")[1]: v.split(":")[0] for v in renderer.get("volumes", [])}
    check(renderer_mounts.get(shm_dir) == mounts.get(shm_dir),
          "compose.yaml: the renderer does not mount the server's shm volume there")
    volume = compose.get("volumes", {}).get(mounts.get(shm_dir), {}) or {}
    check(volume.get("driver_opts", {}).get("type") == "tmpfs",
          "compose.yaml: the shared volume is not memory-backed (tmpfs)")
    check_regions_on_socket("compose.yaml", env, same_host=True)
    check_same_host_client("compose.yaml renderer", renderer.get("command", []), shm_dir,
                           shm_dir)


def check_same_host_pod(name, dep, version, base_maps):
    """A pod with skinserve and a client sharing a memory-backed emptyDir."""
    pod = dep["spec"]["template"]["spec"]
    containers = {c["name"]: c for c in pod["containers"]}
    server = containers.get("skinserve")
    clients = [c for n, c in containers.items() if n != "skinserve"]
    if not check(server is not None and clients, f"{name}: not skinserve plus a client"):
        return
    for c in pod["containers"]:
        check(c["image"].endswith(":" + version), f"{name}: {c['name']} image not {version}")
    check_pod_hardening(name, pod)
    for source in server.get("envFrom", []):
        ref = source.get("configMapRef", {}).get("name")
        check(ref in base_maps, f"{name}: envFrom ConfigMap {ref} is not in base/configmap.yaml")
    check_sizing(name, server, {e["name"]: e.get("value") for e in server.get("env", [])})
    tcp, sockets = listen_addresses(
        next((e.get("value") for e in server.get("env", []) if e["name"] == "SKINSERVE_LISTEN"),
             ""))
    check(not tcp or any(e["name"] == "SKINSERVE_TLS_CERT" for e in server.get("env", [])),
          f"{name}: the server listens on TCP {tcp} without TLS")
    check_probes(name, server, True, None, sockets)
    env = {e["name"]: e.get("value") for e in server.get("env", [])}
    shm_dir = env.get("SKINSERVE_SHM_DIR")
    memory = {v["name"] for v in pod["volumes"] if v.get("emptyDir", {}).get("medium") == "Memory"}
    server_mounts = {m["mountPath"]: m["name"] for m in server["volumeMounts"]}
    check(server_mounts.get(shm_dir) in memory,
          f"{name}: SKINSERVE_SHM_DIR {shm_dir} is not a memory-backed emptyDir")
    sockets = [a[5:] for a in (env.get("SKINSERVE_LISTEN") or "").split(",") if a.startswith("unix:")]
    check(sockets and sockets[0].rsplit("/", 1)[0] == shm_dir,
          f"{name}: no Unix socket in the shared folder {shm_dir}")
    check_regions_on_socket(name, env, same_host=True)
    for client in clients:
        mounts = {m["mountPath"]: m["name"] for m in client["volumeMounts"]}
        check(mounts.get(shm_dir) == server_mounts.get(shm_dir),
              f"{name}: {client['name']} does not share {shm_dir} with skinserve")
        check_same_host_client(f"{name} {client['name']}", client.get("args", []), shm_dir,
                               shm_dir, env.get("SKINSERVE_FRAME_SOCKET"))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    SERVER_BINARY = sys.argv[2]
    main(sys.argv[1])
    for f in failures:
        print("FAIL:", f)
    print("check_manifests: " + ("ok" if not failures else f"{len(failures)} problem(s)"))
    sys.exit(1 if failures else 0)
