#!/usr/bin/env python3
"""Checks that the deployment files agree with each other and with the project.

yamllint checks the syntax and style; this checks what a cluster would only tell us at
apply time, or never: the version label everywhere equals project(VERSION), the CPU the
pods get equals the compute threads they run, the probes are native gRPC probes on the
served port, the grace period outlasts the drain, and the Service, autoscaler and
disruption budget select the Deployment's pods.

usage: check_manifests.py <repository root>
"""
import pathlib
import re
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


def main(root):
    root = pathlib.Path(root)
    cmake = (root / "CMakeLists.txt").read_text()
    version = re.search(r"project\(skinserve\s+VERSION\s+([0-9][0-9.]*)", cmake).group(1)

    docs = {}
    for path in sorted((root / "deploy" / "k8s").glob("*.yaml")):
        for doc in yaml.safe_load_all(path.read_text()):
            if doc:
                docs[doc["kind"]] = doc
                labels = doc["metadata"].get("labels", {})
                check(labels.get("app.kubernetes.io/version") == version,
                      f"{path.name}: {doc['kind']} label app.kubernetes.io/version is "
                      f"{labels.get('app.kubernetes.io/version')!r}, project is {version}")
    for kind in ("Deployment", "Service", "HorizontalPodAutoscaler",
                 "PodDisruptionBudget", "ConfigMap"):
        check(kind in docs, f"k8s/: no {kind}")
    if failures:
        return

    config = docs["ConfigMap"]["data"]
    dep = docs["Deployment"]
    pod = dep["spec"]["template"]
    pod_labels = pod["metadata"]["labels"]
    check(pod_labels.get("app.kubernetes.io/version") == version,
          "Deployment: pod template version label differs from the project version")
    check(dep["spec"]["selector"]["matchLabels"].items() <= pod_labels.items(),
          "Deployment: selector does not match its pod template")
    check(dep["spec"].get("replicas", 1) >= 2, "Deployment: fewer than 2 replicas")

    (container,) = pod["spec"]["containers"]
    check(container["image"].endswith(":" + version),
          f"Deployment: image {container['image']} is not tagged {version}")
    ports = {p["name"]: p["containerPort"] for p in container["ports"]}
    listen_port = int(config["SKINSERVE_LISTEN"].rsplit(":", 1)[1])
    check(ports.get("grpc") == listen_port,
          f"Deployment: containerPort grpc {ports.get('grpc')} != SKINSERVE_LISTEN port")
    # Metrics: the port SKINSERVE_METRICS_LISTEN serves is the containerPort "metrics",
    # and the pod's scrape annotations point at it.
    if check("SKINSERVE_METRICS_LISTEN" in config, "ConfigMap: no SKINSERVE_METRICS_LISTEN"):
        metrics_port = int(config["SKINSERVE_METRICS_LISTEN"].rsplit(":", 1)[1])
        check(ports.get("metrics") == metrics_port,
              f"Deployment: containerPort metrics {ports.get('metrics')} != "
              f"SKINSERVE_METRICS_LISTEN port {metrics_port}")
        notes = pod["metadata"].get("annotations", {})
        check(notes.get("prometheus.io/scrape") == "true" and
              notes.get("prometheus.io/port") == str(metrics_port) and
              notes.get("prometheus.io/path") == "/metrics",
              "Deployment: pod template lacks prometheus.io/scrape, port and path annotations "
              f"for port {metrics_port}")
    # Connection hygiene: connections age out (clients re-resolve and find new replicas),
    # with a grace that lets a frame finish.
    if check("SKINSERVE_MAX_CONNECTION_AGE_SECONDS" in config,
             "ConfigMap: no SKINSERVE_MAX_CONNECTION_AGE_SECONDS"):
        check(float(config["SKINSERVE_MAX_CONNECTION_AGE_SECONDS"]) > 0,
              "ConfigMap: connections never age out")
        check(float(config.get("SKINSERVE_MAX_CONNECTION_AGE_GRACE_SECONDS", 0)) >= 1,
              "ConfigMap: SKINSERVE_MAX_CONNECTION_AGE_GRACE_SECONDS under a second")
    refs = [e["configMapRef"]["name"] for e in container.get("envFrom", [])
            if "configMapRef" in e]
    check(docs["ConfigMap"]["metadata"]["name"] in refs,
          "Deployment: the ConfigMap is not in envFrom")

    threads = int(config["SKINSERVE_THREADS"])
    res = container["resources"]
    check(cpu_cores(res["requests"]["cpu"]) == threads == cpu_cores(res["limits"]["cpu"]),
          f"Deployment: cpu request/limit {res['requests']['cpu']}/{res['limits']['cpu']} "
          f"!= SKINSERVE_THREADS {threads}")
    if "POCL_MAX_PTHREAD_COUNT" in config:
        check(int(config["POCL_MAX_PTHREAD_COUNT"]) == threads,
              "ConfigMap: POCL_MAX_PTHREAD_COUNT != SKINSERVE_THREADS")

    for probe in ("readinessProbe", "livenessProbe", "startupProbe"):
        p = container.get(probe)
        if check(p is not None, f"Deployment: no {probe}"):
            check(p.get("grpc", {}).get("port") == listen_port,
                  f"Deployment: {probe} is not a native grpc probe on port {listen_port}")

    grace = pod["spec"].get("terminationGracePeriodSeconds", 30)
    if check("SKINSERVE_DRAIN_SECONDS" in config, "ConfigMap: no SKINSERVE_DRAIN_SECONDS"):
        drain = duration_seconds(config["SKINSERVE_DRAIN_SECONDS"])
        pre_stop = container.get("lifecycle", {}).get("preStop", {})
        pause = 0.0
        if "exec" in pre_stop and pre_stop["exec"]["command"][0] == "sleep":
            pause = float(pre_stop["exec"]["command"][1])
        if "sleep" in pre_stop:
            pause = float(pre_stop["sleep"]["seconds"])
        check(grace > pause + drain,
              f"Deployment: terminationGracePeriodSeconds {grace} <= preStop {pause} s + "
              f"drain {drain} s")

    svc = docs["Service"]
    check(svc["spec"].get("clusterIP") == "None", "Service: not headless (clusterIP: None)")
    check(svc["spec"]["selector"].items() <= pod_labels.items(),
          "Service: selector does not match the pods")
    svc_ports = svc["spec"]["ports"]
    check(any(p.get("targetPort") in ("grpc", listen_port) for p in svc_ports),
          "Service: no port to the grpc containerPort")

    hpa = docs["HorizontalPodAutoscaler"]
    check(hpa["apiVersion"] == "autoscaling/v2", "HPA: not autoscaling/v2")
    check(hpa["spec"]["scaleTargetRef"]["name"] == dep["metadata"]["name"],
          "HPA: does not target the Deployment")
    check(any(m["type"] == "Resource" and m["resource"]["name"] == "cpu"
              for m in hpa["spec"]["metrics"]), "HPA: no CPU metric")
    check(hpa["spec"]["minReplicas"] >= 2, "HPA: minReplicas below 2")

    pdb = docs["PodDisruptionBudget"]
    check(pdb["spec"]["selector"]["matchLabels"].items() <= pod_labels.items(),
          "PDB: selector does not match the pods")

    dockerfile = (root / "deploy" / "Dockerfile").read_text()
    m = re.search(r"^ARG VERSION=(\S+)", dockerfile, re.M)
    check(m and m.group(1) == version, "Dockerfile: ARG VERSION default != project version")
    check("org.opencontainers.image.version" in dockerfile, "Dockerfile: no version label")
    check(re.search(r"^HEALTHCHECK", dockerfile, re.M) is not None, "Dockerfile: no HEALTHCHECK")
    check(re.search(r"^USER (?!0\b|root\b)", dockerfile, re.M) is not None,
          "Dockerfile: does not switch to a non-root USER")

    compose = yaml.safe_load((root / "deploy" / "compose.yaml").read_text())
    image = compose["services"]["server"]["image"]
    check(f":-{version}}}" in image, f"compose.yaml: default image version is not {version}")
    server_env = compose["services"]["server"].get("environment", {})
    if check("SKINSERVE_METRICS_LISTEN" in server_env, "compose.yaml: no SKINSERVE_METRICS_LISTEN"):
        compose_metrics = server_env["SKINSERVE_METRICS_LISTEN"].rsplit(":", 1)[1]
        check(any(str(p).endswith(f":{compose_metrics}")
                  for p in compose["services"]["server"].get("ports", [])),
              f"compose.yaml: the metrics port {compose_metrics} is not published")
    load = compose["services"]["load"]
    check(load["depends_on"]["server"]["condition"] == "service_healthy",
          "compose.yaml: load does not wait for a healthy server")
    check_same_host_compose(compose)
    for path in sorted((root / "deploy" / "k8s" / "same-host").glob("*.yaml")):
        for doc in yaml.safe_load_all(path.read_text()):
            if doc and doc["kind"] == "Deployment":
                check_same_host_pod(path.name, doc, version)


def flag(args, name):
    """The value of --name=VALUE in a list of arguments, or None."""
    for a in args:
        if a.startswith(f"--{name}="):
            return a.split("=", 1)[1]
    return None


def check_same_host_client(where, args, shm_dir, socket_dir):
    """A same-host client: the shared-memory data plane in the server's --shm-dir, and
    gRPC over the server's Unix socket in the shared folder."""
    check("--shared-memory" in args or flag(args, "data-planes") in ("shm", "grpc,shm"),
          f"{where}: the client does not use the shared-memory data plane")
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
    check_same_host_client("compose.yaml renderer", renderer.get("command", []), shm_dir,
                           shm_dir)


def check_same_host_pod(name, dep, version):
    """A pod with skinserve and a client sharing a memory-backed emptyDir."""
    pod = dep["spec"]["template"]["spec"]
    containers = {c["name"]: c for c in pod["containers"]}
    server = containers.get("skinserve")
    clients = [c for n, c in containers.items() if n != "skinserve"]
    if not check(server is not None and clients, f"{name}: not skinserve plus a client"):
        return
    for c in pod["containers"]:
        check(c["image"].endswith(":" + version), f"{name}: {c['name']} image not {version}")
    env = {e["name"]: e.get("value") for e in server.get("env", [])}
    shm_dir = env.get("SKINSERVE_SHM_DIR")
    memory = {v["name"] for v in pod["volumes"] if v.get("emptyDir", {}).get("medium") == "Memory"}
    server_mounts = {m["mountPath"]: m["name"] for m in server["volumeMounts"]}
    check(server_mounts.get(shm_dir) in memory,
          f"{name}: SKINSERVE_SHM_DIR {shm_dir} is not a memory-backed emptyDir")
    sockets = [a[5:] for a in (env.get("SKINSERVE_LISTEN") or "").split(",") if a.startswith("unix:")]
    check(sockets and sockets[0].rsplit("/", 1)[0] == shm_dir,
          f"{name}: no Unix socket in the shared folder {shm_dir}")
    for client in clients:
        mounts = {m["mountPath"]: m["name"] for m in client["volumeMounts"]}
        check(mounts.get(shm_dir) == server_mounts.get(shm_dir),
              f"{name}: {client['name']} does not share {shm_dir} with skinserve")
        check_same_host_client(f"{name} {client['name']}", client.get("args", []), shm_dir,
                               shm_dir)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
    for f in failures:
        print("FAIL:", f)
    print("check_manifests: " + ("ok" if not failures else f"{len(failures)} problem(s)"))
    sys.exit(1 if failures else 0)
