"""deploy/k8s: schema-valid for Kubernetes (kubernetes-validate, strict: unknown fields are
errors) and consistent with the images, the compose file and each other."""
import re
import subprocess
import sys

import pytest
import yaml

from farm_harness import ROOT

K8S = ROOT / "deploy" / "k8s"
MANIFESTS = sorted(K8S.glob("*.yaml"))
KUBERNETES_VERSION = "1.30.0"


def validate(*paths):
    return subprocess.run([sys.executable, "-m", "kubernetes_validate", "--strict", "-k",
                           KUBERNETES_VERSION, *map(str, paths)], capture_output=True, text=True,
                          timeout=120)


def resources():
    found = {}
    for path in MANIFESTS:
        for document in yaml.safe_load_all(path.read_text()):
            if document and document.get("kind") != "Kustomization":
                found[(document["kind"], document["metadata"]["name"])] = document
    return found


def container(resources, deployment):
    [only] = resources[("Deployment", deployment)]["spec"]["template"]["spec"]["containers"]
    return only


def flag(args, name):
    return args[args.index(name) + 1]


@pytest.mark.parametrize("path", [p for p in MANIFESTS if p.name != "kustomization.yaml"],
                         ids=lambda p: p.name)
def test_manifest_is_valid_kubernetes(path):
    result = validate(path)
    assert result.returncode == 0, result.stdout + result.stderr


def test_the_validator_refuses_a_broken_manifest(tmp_path):
    broken = (K8S / "worker.yaml").read_text().replace("replicas: 3", 'replicas: "three"')
    broken = broken.replace("imagePullPolicy: IfNotPresent", "imagePullPolicy: IfNotPresent\n"
                            "          restartPolicyy: Always")
    (tmp_path / "worker.yaml").write_text(broken)
    result = validate(tmp_path / "worker.yaml")
    assert result.returncode != 0
    assert "three" in result.stdout + result.stderr


def test_kustomization_lists_every_manifest():
    kustomization = yaml.safe_load((K8S / "kustomization.yaml").read_text())
    listed = set(kustomization["resources"])
    assert listed == {p.name for p in MANIFESTS if p.name != "kustomization.yaml"}


def test_workers_reach_the_coordinator_service():
    found = resources()
    service = found[("Service", "tcfarm-coordinator")]
    ports = {p["name"]: p["port"] for p in service["spec"]["ports"]}
    coordinator = container(found, "tcfarm-coordinator")
    worker = container(found, "tcfarm-worker")
    assert flag(worker["args"], "--coordinator") == f"tcp://tcfarm-coordinator:{ports['zmq']}"
    container_ports = {p["name"]: p["containerPort"] for p in coordinator["ports"]}
    assert flag(coordinator["args"], "--http").endswith(f":{container_ports['http']}")
    assert flag(coordinator["args"], "--zmq").endswith(f":{container_ports['zmq']}")
    # The service selects the coordinator's pods, and only them.
    labels = found[("Deployment", "tcfarm-coordinator")]["spec"]["template"]["metadata"]["labels"]
    assert service["spec"]["selector"].items() <= labels.items()


def test_probes_and_scrape_annotations_name_real_ports():
    found = resources()
    for name in ("tcfarm-coordinator", "tcfarm-worker"):
        spec = container(found, name)
        ports = {p["name"]: p["containerPort"] for p in spec["ports"]}
        for probe in ("livenessProbe", "readinessProbe"):
            if probe in spec:
                assert spec[probe]["httpGet"]["port"] in ports, (name, probe)
                assert spec[probe]["httpGet"]["path"] == "/healthz"
        annotations = found[("Deployment", name)]["spec"]["template"]["metadata"]["annotations"]
        assert int(annotations["prometheus.io/port"]) in ports.values(), name
    worker = container(found, "tcfarm-worker")
    assert flag(worker["args"], "--metrics").endswith(f":{annotations['prometheus.io/port']}")


def test_manifests_run_the_images_compose_builds_as_their_user():
    compose = yaml.safe_load((ROOT / "docker-compose.yml").read_text())
    dockerfile = (ROOT / "deploy" / "Dockerfile").read_text()
    [image_user] = set(re.findall(r"^USER (\d+)$", dockerfile, re.M))
    found = resources()
    for service, deployment in (("coordinator", "tcfarm-coordinator"), ("worker", "tcfarm-worker")):
        spec = container(found, deployment)
        assert spec["image"] == compose["services"][service]["image"]
        pod = found[("Deployment", deployment)]["spec"]["template"]["spec"]
        assert pod["securityContext"]["runAsNonRoot"] is True
        assert str(pod["securityContext"]["runAsUser"]) == image_user


def test_the_coordinators_api_tokens_come_from_a_secret():
    found = resources()
    coordinator = container(found, "tcfarm-coordinator")
    pod = found[("Deployment", "tcfarm-coordinator")]["spec"]["template"]["spec"]
    env = {e["name"]: e["value"] for e in coordinator.get("env", [])}
    mounts = {m["name"]: m["mountPath"] for m in coordinator["volumeMounts"]}
    secrets = {v["name"]: v["secret"]["secretName"] for v in pod["volumes"] if "secret" in v}
    assert secrets["api-tokens"] == "tcfarm-api-tokens"
    # The image's entrypoint hands TCFARM_API_TOKENS to --api-tokens: a file of that Secret.
    assert env["TCFARM_API_TOKENS"].startswith(mounts["api-tokens"] + "/")
    assert "--api-tokens" not in coordinator["args"]
    assert "--insecure-no-auth" not in coordinator["args"]
    assert "ENV TCFARM_API_TOKENS=" in (ROOT / "deploy" / "Dockerfile").read_text()
    assert 'ENTRYPOINT ["coordinator-entrypoint"]' in (ROOT / "deploy" / "Dockerfile").read_text()


def test_both_sides_read_their_curve_keys_from_mounted_secrets():
    """CURVE key files name paths inside mounts, the secret ones from Secrets (never a
    ConfigMap), and only the coordinator holds its own secret."""
    found = resources()
    for deployment, secret_flags in (("tcfarm-coordinator", ["--curve-secret"]), ("tcfarm-worker", ["--curve-secret"])):
        spec = container(found, deployment)
        pod = found[("Deployment", deployment)]["spec"]["template"]["spec"]
        volumes = {v["name"]: v for v in pod["volumes"]}
        mounts = {m["mountPath"]: m["name"] for m in spec["volumeMounts"]}
        for name in secret_flags + (["--worker-keys"] if deployment == "tcfarm-coordinator" else ["--coordinator-key"]):
            path = flag(spec["args"], name)
            [mount] = [m for m in mounts if path == m or path.startswith(m + "/")]
            if name == "--curve-secret":
                assert "secret" in volumes[mounts[mount]], (deployment, name)
                assert pod["securityContext"]["fsGroup"] == pod["securityContext"]["runAsUser"]
    worker_secret = {v["name"]: v for v in found[("Deployment", "tcfarm-worker")]["spec"]["template"]["spec"]["volumes"]}
    coordinator_secret = {v["name"]: v for v in found[("Deployment", "tcfarm-coordinator")]["spec"]["template"]["spec"]["volumes"]}
    assert worker_secret["curve-key"]["secret"]["secretName"] != coordinator_secret["curve-key"]["secret"]["secretName"]
