"""Static checks of docker/ (Docker cannot run here): the compose file parses and wires the service
to PostgreSQL 16, and the Dockerfile copies paths that exist and starts the server without the demo
(whose account's password is public), since both listen on every interface."""
from __future__ import annotations

import json
import re
import shlex
import tomllib
from pathlib import Path

import pytest

from app.core.paths import PROJECT_ROOT

DOCKER = PROJECT_ROOT / "docker"
yaml = pytest.importorskip("yaml", reason="PyYAML is needed to parse docker/compose.yaml")


@pytest.fixture(scope="module")
def compose() -> dict:
    data = yaml.safe_load((DOCKER / "compose.yaml").read_text(encoding="utf-8"))
    assert isinstance(data, dict)
    return data


def _instructions(dockerfile: Path) -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments) pairs, continuation lines joined, comments dropped."""
    text = re.sub(r"\\\n", " ", dockerfile.read_text(encoding="utf-8"))
    out = []
    for line in text.splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            word, _, rest = line.partition(" ")
            out.append((word.upper(), rest.strip()))
    return out


def test_compose_service_against_postgres16(compose: dict) -> None:
    services = compose["services"]
    assert services["db"]["image"] == "postgres:16"
    env = services["app"]["environment"]
    assert env["V3D_DATABASE_URL"] == "postgresql+psycopg://v3d:v3d@db:5432/v3d"
    db_env = services["db"]["environment"]
    assert (db_env["POSTGRES_USER"], db_env["POSTGRES_PASSWORD"], db_env["POSTGRES_DB"]) == ("v3d", "v3d", "v3d")
    assert services["app"]["depends_on"]["db"]["condition"] == "service_healthy"
    for name in ("db", "app"):
        assert services[name]["healthcheck"]["test"], name


def test_compose_serves_without_the_demo(compose: dict) -> None:
    assert compose["services"]["app"]["command"] == ["v3d", "serve", "--host", "0.0.0.0"]


def test_compose_named_volumes_are_declared(compose: dict) -> None:
    declared = set(compose.get("volumes") or {})
    used = {v.split(":", 1)[0] for s in compose["services"].values() for v in s.get("volumes", [])}
    named = {v for v in used if not v.startswith((".", "/", "~"))}
    assert named and named <= declared, (named, declared)
    assert any(v.endswith(":/var/lib/postgresql/data") for v in compose["services"]["db"]["volumes"])


def test_compose_builds_the_dockerfile_from_the_repository_root(compose: dict) -> None:
    build = compose["services"]["app"]["build"]
    context = (DOCKER / build["context"]).resolve()
    assert context == PROJECT_ROOT.resolve()
    assert (context / build["dockerfile"]).is_file()


def test_dockerfile_base_copies_and_command() -> None:
    instr = _instructions(DOCKER / "Dockerfile")
    assert instr[0] == ("FROM", "python:3.11-slim")
    for word, args in instr:
        if word == "COPY":
            *sources, _dest = shlex.split(args)
            for src in sources:
                if any(ch in src for ch in "*?["):
                    continue  # optional files matched by a wildcard
                assert (PROJECT_ROOT / src).exists(), f"COPY source {src} missing from the repository"
    cmd = [json_arg.strip('" ') for json_arg in dict(instr)["CMD"].strip("[]").split(",")]
    assert cmd == ["v3d", "serve", "--host", "0.0.0.0"]  # never --demo: its password is public
    scripts = tomllib.loads((PROJECT_ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["scripts"]
    assert "v3d" in scripts


def test_healthchecks_query_an_api_route_that_exists(compose: dict) -> None:
    """The probe asks /api/health (it needs the database, not a login); the route must be registered
    and public (an anonymous probe of any other API route gets 401)."""
    probe = " ".join(compose["services"]["app"]["healthcheck"]["test"])
    path = re.search(r"127\.0\.0\.1:8000(/[\w/]+)", probe).group(1)
    assert path in (DOCKER / "Dockerfile").read_text(encoding="utf-8")
    from app.api.authentication import is_protected
    from app.core.config import Settings
    from app.main import create_app

    assert "get" in create_app(Settings(database_url="sqlite://")).openapi()["paths"][path]
    assert not is_protected(path)


def test_the_readme_and_the_docker_files_show_how_to_make_the_first_admin() -> None:
    """Without the demo, a fresh container has no account: the README and both Docker files say how to create
    the first admin in it (``docker compose ... run --rm app v3d users add NAME --role admin``)."""
    readme = (PROJECT_ROOT / "README.md").read_text(encoding="utf-8")
    assert "docker compose -f docker/compose.yaml run --rm app v3d users add NAME --role admin" in readme
    assert "run --rm app v3d users add NAME --role admin" in (DOCKER / "compose.yaml").read_text(encoding="utf-8")
    assert "v3d users add NAME --role admin" in (DOCKER / "Dockerfile").read_text(encoding="utf-8")


def test_compose_and_the_readme_show_how_to_name_the_served_host(compose: dict) -> None:
    """Issue 27, item 3: a Host other than a loopback name or V3D_ALLOWED_HOSTS gets 400, so the Docker files pass
    the served name on and the README's deployment part says how to set it."""
    assert compose["services"]["app"]["environment"]["V3D_ALLOWED_HOSTS"] == "${V3D_ALLOWED_HOSTS:-}"
    text = (DOCKER / "compose.yaml").read_text(encoding="utf-8")
    assert "V3D_ALLOWED_HOSTS=v3d.example.org docker compose -f docker/compose.yaml up -d" in text
    readme = (DOCKER.parent / "README.md").read_text(encoding="utf-8")
    assert "V3D_ALLOWED_HOSTS=v3d.example.org docker compose -f docker/compose.yaml up -d" in readme
    assert "DNS rebinding" in readme


def test_the_two_node_compose_shares_only_the_database_and_the_object_store() -> None:
    """docker/compose.nodes.yaml (docs/deploy.md): two nodes of distinct names, each with a volume of its own, the
    same PostgreSQL database and S3 bucket (SeaweedFS serving S3), behind nginx passing requests to both."""
    nodes_compose = yaml.safe_load((DOCKER / "compose.nodes.yaml").read_text(encoding="utf-8"))
    services = nodes_compose["services"]
    nodes = [services["node-a"], services["node-b"]]
    envs = [n["environment"] for n in nodes]
    assert [e["V3D_NODE_NAME"] for e in envs] == ["node-a", "node-b"]
    shared = ("V3D_DATABASE_URL", "V3D_STORAGE_URL", "AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_ENDPOINT_URL",
              "AWS_DEFAULT_REGION")
    assert all(envs[0][k] == envs[1][k] for k in shared)
    assert envs[0]["V3D_DATABASE_URL"] == "postgresql+psycopg://v3d:v3d@db:5432/v3d"
    assert envs[0]["V3D_STORAGE_URL"].startswith("s3://") and envs[0]["AWS_ENDPOINT_URL"] == "http://s3:8333"
    assert services["db"]["image"] == "postgres:16"
    assert services["s3"]["image"] == "chrislusf/seaweedfs" and services["s3"]["command"][:1] == ["server"]
    assert "-s3" in services["s3"]["command"]
    bucket = envs[0]["V3D_STORAGE_URL"].removeprefix("s3://").split("/", 1)[0]
    assert f"s3.bucket.create -name {bucket}" in " ".join(services["s3-bucket"]["entrypoint"])
    keys = json.loads((DOCKER / "seaweedfs-s3.json").read_text(encoding="utf-8"))["identities"][0]["credentials"][0]
    assert (keys["accessKey"], keys["secretKey"]) == (envs[0]["AWS_ACCESS_KEY_ID"], envs[0]["AWS_SECRET_ACCESS_KEY"])
    volumes = [n["volumes"] for n in nodes]
    assert volumes[0] != volumes[1]
    assert all(v.split(":", 1)[0] in nodes_compose["volumes"] for vs in volumes for v in vs)
    assert all(n["command"] == ["v3d", "serve", "--host", "0.0.0.0"] for n in nodes)
    lb_address = services["lb"]["networks"]["v3d"]["ipv4_address"]
    assert json.loads(envs[0]["V3D_TRUSTED_PROXIES"]) == [lb_address]
    conf = (DOCKER / "nginx.nodes.conf").read_text(encoding="utf-8")
    assert "server node-a:8000" in conf and "server node-b:8000" in conf
    mounted = {v.split(":")[1] for v in services["lb"]["volumes"]}
    assert "/etc/nginx/conf.d/default.conf" in mounted
