#!/usr/bin/python3
"""Client-side checks of deploy/k8s, with no cluster (docs/SCALING.md says what this does not
prove). Parses every manifest the kustomization lists and checks what vsurg relies on:
  - every object has apiVersion, kind and a name, and its kind is one we expect;
  - every Service, PodDisruptionBudget and controller selects the pods it is meant to (selector
    labels present on the pod template);
  - every port a Service targets by name is declared by the pods it selects;
  - the control plane is ready by the gRPC health service on its gRPC port, runs >= 2 replicas;
  - the simulation nodes expose UDP on a hostPort and tell stations the host's address, give a
    SIGTERM drain its time (terminationGracePeriodSeconds > --drain-timeout), one per machine;
  - every secret a pod reads exists in the kustomization (defined, or issued by a Certificate);
  - the internal API runs mutual TLS: both roles have the three TLS files and no --allow-insecure;
    the control replicas' certificate names the control name, each node's names its pod (through
    cert-manager's csi-driver), and the nodes' probe reaches the plaintext health port.
Exits 1 with one line per problem. Usage: deploy/k8s/check.py [DIR]"""
import os
import sys

import yaml

KINDS = {"Namespace", "Secret", "Service", "Deployment", "StatefulSet", "PodDisruptionBudget",
         "Certificate", "Issuer"}


def load(directory):
    with open(os.path.join(directory, "kustomization.yaml")) as f:
        k = yaml.safe_load(f)
    docs = []
    for name in k["resources"]:
        with open(os.path.join(directory, name)) as f:
            docs += [(name, d) for d in yaml.safe_load_all(f) if d]
    return docs


def arg(container, flag):
    for a in container.get("args", []):
        if a.startswith(flag + "="):
            return a.split("=", 1)[1]
    return None


def main():
    directory = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
    docs = load(directory)
    problems = []
    by_kind = {}
    for name, d in docs:
        for field in ("apiVersion", "kind"):
            if field not in d:
                problems.append(f"{name}: an object without {field}")
        if "name" not in d.get("metadata", {}):
            problems.append(f"{name}: a {d.get('kind')} without a name")
        if d.get("kind") not in KINDS:
            problems.append(f"{name}: unexpected kind {d.get('kind')}")
        by_kind.setdefault(d.get("kind"), []).append(d)

    workloads = by_kind.get("Deployment", []) + by_kind.get("StatefulSet", [])
    pods = {w["metadata"]["name"]: w["spec"]["template"] for w in workloads}

    def selected(selector):
        return [t for t in pods.values()
                if all(t["metadata"]["labels"].get(k) == v for k, v in selector.items())]

    for w in workloads:
        n = w["metadata"]["name"]
        want = w["spec"]["selector"]["matchLabels"]
        if w["spec"]["template"] not in selected(want):
            problems.append(f"{n}: its selector does not match its own pods")
    for s in by_kind.get("Service", []):
        n = s["metadata"]["name"]
        targets = selected(s["spec"]["selector"])
        if not targets:
            problems.append(f"Service {n} selects no pods")
        declared = {p.get("name") for t in targets for c in t["spec"]["containers"]
                    for p in c.get("ports", [])}
        for p in s["spec"]["ports"]:
            t = p.get("targetPort")
            if isinstance(t, str) and t not in declared:
                problems.append(f"Service {n}: target port {t} is not declared by its pods")
    for b in by_kind.get("PodDisruptionBudget", []):
        if not selected(b["spec"]["selector"]["matchLabels"]):
            problems.append(f"PodDisruptionBudget {b['metadata']['name']} selects no pods")

    secrets = {s["metadata"]["name"]: s for s in by_kind.get("Secret", [])}
    issued = {c["spec"]["secretName"]: c for c in by_kind.get("Certificate", [])}
    issuers = {i["metadata"]["name"] for i in by_kind.get("Issuer", [])}
    for c in by_kind.get("Certificate", []):
        if c["spec"].get("issuerRef", {}).get("name") not in issuers:
            problems.append(f"Certificate {c['metadata']['name']}: its issuer is not defined")
    for w in workloads:
        spec = w["spec"]["template"]["spec"]
        refs = [v["secret"]["secretName"] for v in spec.get("volumes", []) if "secret" in v]
        for c in spec["containers"]:
            for e in c.get("env", []):
                ref = e.get("valueFrom", {}).get("secretKeyRef")
                if ref:
                    refs.append(ref["name"])
                    if ref["name"] in secrets and ref["key"] not in secrets[ref["name"]].get("stringData", {}):
                        problems.append(f"{w['metadata']['name']}: secret {ref['name']} has no key {ref['key']}")
        for r in refs:
            if r not in secrets and r not in issued:
                problems.append(f"{w['metadata']['name']}: reads secret {r}, which is not defined")

    control = [w for w in workloads if any(arg(c, "--role") == "control"
                                           for c in w["spec"]["template"]["spec"]["containers"])]
    sims = [w for w in workloads if any(arg(c, "--role") == "sim"
                                        for c in w["spec"]["template"]["spec"]["containers"])]
    if len(control) != 1 or control[0]["kind"] != "Deployment":
        problems.append("the control plane is not one Deployment")
    else:
        c = control[0]["spec"]["template"]["spec"]["containers"][0]
        port = int(arg(c, "--listen").rsplit(":", 1)[1])
        if c.get("readinessProbe", {}).get("grpc", {}).get("port") != port:
            problems.append("control: readiness is not the gRPC health service on --listen's port")
        if control[0]["spec"].get("replicas", 1) < 2:
            problems.append("control: fewer than 2 replicas")
    if len(sims) != 1 or sims[0]["kind"] != "StatefulSet":
        problems.append("the simulation nodes are not one StatefulSet")
    else:
        spec = sims[0]["spec"]["template"]["spec"]
        c = spec["containers"][0]
        udp = int(arg(c, "--udp-port"))
        ports = [p for p in c.get("ports", []) if p.get("protocol") == "UDP"]
        if not any(p["containerPort"] == udp and p.get("hostPort") == udp for p in ports):
            problems.append("sim: the UDP port is not exposed on the machine (hostPort)")
        if arg(c, "--public-host") != "$(HOST_IP)":
            problems.append("sim: stations are not told the machine's address")
        grace = spec.get("terminationGracePeriodSeconds", 30)
        if grace <= float(arg(c, "--drain-timeout") or 600):
            problems.append("sim: the grace period does not cover the drain")
        anti = spec.get("affinity", {}).get("podAntiAffinity", {})
        if not anti.get("requiredDuringSchedulingIgnoredDuringExecution"):
            problems.append("sim: two nodes could share a machine (and its hostPort)")
        health = arg(c, "--cluster-health-listen")
        if not health or c.get("readinessProbe", {}).get("grpc", {}).get("port") != int(health.rsplit(":", 1)[1]):
            problems.append("sim: readiness is not the gRPC health service on --cluster-health-listen")
        csi = [v["csi"] for v in spec.get("volumes", []) if v.get("csi", {}).get("driver") == "csi.cert-manager.io"]
        if not csi or csi[0].get("volumeAttributes", {}).get("csi.cert-manager.io/dns-names") != "${POD_NAME}":
            problems.append("sim: no certificate naming the pod (the node name)")
        elif csi[0]["volumeAttributes"].get("csi.cert-manager.io/issuer-name") not in issuers:
            problems.append("sim: the nodes' certificates come from an issuer that is not defined")
        if arg(c, "--node-name") != "$(POD_NAME)":
            problems.append("sim: the node name is not the pod name (its certificate names the pod)")
    for w in control + sims:
        for c in w["spec"]["template"]["spec"]["containers"]:
            if "--allow-insecure" in c.get("args", []):
                problems.append(f"{w['metadata']['name']}: --allow-insecure (the internal API must run mutual TLS)")
            for flag in ("--cluster-tls-cert", "--cluster-tls-key", "--cluster-tls-ca"):
                if not arg(c, flag):
                    problems.append(f"{w['metadata']['name']}: no {flag}")
    if control:
        spec = control[0]["spec"]["template"]["spec"]
        mounted = {m["name"]: m["mountPath"] for m in spec["containers"][0].get("volumeMounts", [])}
        tls = [v for v in spec.get("volumes", []) if "secret" in v and v["secret"]["secretName"] in issued
               and arg(spec["containers"][0], "--cluster-tls-cert").startswith(mounted.get(v["name"], "?") + "/")]
        name = arg(spec["containers"][0], "--cluster-control-name") or "vsurg-control"
        if not tls or name not in issued[tls[0]["secret"]["secretName"]]["spec"].get("dnsNames", []):
            problems.append(f"control: its internal certificate does not name {name}")

    for p in problems:
        print("k8s check:", p)
    print(f"k8s check: {len(docs)} objects, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
