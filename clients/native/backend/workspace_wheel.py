"""The build backend (PEP 517) of `pip install ./clients/native`: a wheel of the workspace's
own release build of the module.

The module's library is a member of the cargo workspace, and cargo resolves a dependency's
features over everything one command builds. Built alone (`cargo build -p graybox-native`, or
maturin, which builds the member alone), the inference core gets other features than in the
workspace's build, where the service turns on its Burn, database and OpenAPI parts, so the core
and everything above it compile a second time (about three minutes on 2 cores) into a second
copy. This backend asks cargo for the workspace's build instead (nothing to do when the
service's build or the tests already made it) and packs `lib_native.so` with the Python
package into a wheel: the abi3 tag of CPython 3.10 and later, for this platform.
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

try:
    import tomllib
except ImportError:  # Python 3.10: the same parser, installed by build-system.requires
    import tomli as tomllib

HERE = Path(__file__).resolve().parent.parent
PACKAGE = "graybox_native"
EXTENSION = "_native"
TAG = "cp310-abi3"


def get_requires_for_build_wheel(config_settings=None):
    return []


def prepare_metadata_for_build_wheel(metadata_directory, config_settings=None):
    project = _project()
    info = Path(metadata_directory) / _dist_info(project)
    info.mkdir(parents=True, exist_ok=True)
    (info / "METADATA").write_text(_metadata(project))
    (info / "WHEEL").write_text(_wheel_file())
    return info.name


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    project = _project()
    library = _build_library()
    name = f"{_dist_name(project)}-{project['version']}-{TAG}-{_platform()}.whl"
    files = _package_files()
    files[f"{PACKAGE}/{EXTENSION}.abi3.so"] = library.read_bytes()
    info = _dist_info(project)
    files[f"{info}/METADATA"] = _metadata(project).encode()
    files[f"{info}/WHEEL"] = _wheel_file().encode()
    _write_wheel(Path(wheel_directory) / name, files, f"{info}/RECORD")
    return name


def _project() -> dict:
    with open(HERE / "pyproject.toml", "rb") as f:
        return tomllib.load(f)["project"]


def _build_library() -> Path:
    """The workspace's release build; returns the module's shared library in it."""
    meta = json.loads(_cargo(["metadata", "--format-version", "1", "--no-deps"], capture=True))
    root, target = Path(meta["workspace_root"]), Path(meta["target_directory"])
    _cargo(["build", "--release", "--locked", "--workspace"], cwd=root)
    suffix = {"darwin": "dylib", "win32": "dll"}.get(sys.platform, "so")
    prefix = "" if sys.platform == "win32" else "lib"
    library = target / "release" / f"{prefix}{EXTENSION}.{suffix}"
    if not library.is_file():
        raise RuntimeError(f"cargo's build made no {library}")
    return library


def _cargo(args: list[str], cwd: Path | None = None, capture: bool = False) -> str:
    cargo = os.environ.get("CARGO") or shutil.which("cargo")
    if cargo is None:
        raise RuntimeError("building graybox_native needs cargo (Rust 1.95 or newer) on PATH")
    # cargo's progress goes to stderr, where pip shows it with -v or when the build fails.
    out = subprocess.run([cargo, *args], cwd=cwd or HERE, check=True,
                         stdout=subprocess.PIPE if capture else sys.stderr)
    return out.stdout.decode() if capture else ""


def _package_files() -> dict[str, bytes]:
    source = HERE / "python" / PACKAGE
    return {
        f"{PACKAGE}/{p.relative_to(source).as_posix()}": p.read_bytes()
        for p in sorted(source.rglob("*"))
        if p.is_file() and "__pycache__" not in p.parts
    }


def _dist_name(project: dict) -> str:
    return project["name"].replace("-", "_")


def _dist_info(project: dict) -> str:
    return f"{_dist_name(project)}-{project['version']}.dist-info"


def _platform() -> str:
    return sysconfig.get_platform().replace("-", "_").replace(".", "_")


def _metadata(project: dict) -> str:
    lines = [
        "Metadata-Version: 2.1",
        f"Name: {project['name']}",
        f"Version: {project['version']}",
        f"Summary: {project['description']}",
        f"Requires-Python: {project['requires-python']}",
    ]
    if "license" in project:
        lines.append(f"License: {project['license']['text']}")
    lines += [f"Requires-Dist: {d}" for d in project.get("dependencies", [])]
    return "\n".join(lines) + "\n"


def _wheel_file() -> str:
    return ("Wheel-Version: 1.0\nGenerator: graybox workspace_wheel\nRoot-Is-Purelib: false\n"
            f"Tag: {TAG}-{_platform()}\n")


def _write_wheel(path: Path, files: dict[str, bytes], record: str) -> None:
    rows = []
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as whl:
        for name, data in files.items():
            digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=")
            rows.append(f"{name},sha256={digest.decode()},{len(data)}")
            whl.writestr(_entry(name), data)
        rows.append(f"{record},,")
        whl.writestr(_entry(record), "\n".join(rows) + "\n")


def _entry(name: str) -> zipfile.ZipInfo:
    # Executable for the shared library, readable for the rest; a fixed date so that the same
    # build packs into the same bytes.
    info = zipfile.ZipInfo(name, date_time=(2020, 1, 1, 0, 0, 0))
    info.external_attr = (0o755 if name.endswith(".so") else 0o644) << 16
    info.compress_type = zipfile.ZIP_DEFLATED
    return info
