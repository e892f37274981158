"""Builds graybox-client, generating its gRPC stubs from the service's protos at build time.

The protos' source of truth is `proto/` at the repository root. pip (>= 21.3) builds a local
directory in place, so `../../proto` is there and is copied into the package; an sdist carries
that copy (graybox_client/proto/), which is then used instead. Nothing generated is committed,
so the client cannot drift from the proto the server was built with.
"""

import re
import shutil
import tempfile
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.command.sdist import sdist

HERE = Path(__file__).resolve().parent
PKG = "graybox_client"
REPO_PROTO = HERE.parent.parent / "proto"
PACKAGED_PROTO = HERE / PKG / "proto"


def proto_root() -> Path:
    """The repository's protos when building from a checkout, else the sdist's copy."""
    for root in (REPO_PROTO, PACKAGED_PROTO):
        if (root / "graybox" / "v1" / "dynamics.proto").is_file():
            return root
    raise SystemExit(f"graybox-client: no protos in {REPO_PROTO} or {PACKAGED_PROTO}")


def copy_protos(dest: Path) -> Path:
    """Copies every .proto under the proto root into `dest` (kept in the package as the
    schema the stubs were made from) and returns `dest`."""
    src = proto_root()
    if src.resolve() != dest.resolve():
        for f in src.rglob("*.proto"):
            out = dest / f.relative_to(src)
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(f, out)
    return dest


def generate(pkg_dir: Path) -> None:
    """Runs grpcio-tools' protoc on graybox/v1/*.proto into `pkg_dir/_pb`.

    protoc writes absolute imports (`from graybox.v1 import dynamics_pb2`) that would need a
    top-level `graybox` package; the modules are flattened into `_pb` and those imports made
    relative instead, so nothing outside `graybox_client` is installed.
    """
    import grpc_tools
    from grpc_tools import protoc

    proto = copy_protos(pkg_dir / "proto")
    sources = sorted(p.relative_to(proto).as_posix() for p in (proto / "graybox" / "v1").glob("*.proto"))
    well_known = Path(grpc_tools.__file__).parent / "_proto"
    out = pkg_dir / "_pb"
    with tempfile.TemporaryDirectory() as tmp:
        args = ["grpc_tools.protoc", f"-I{proto}", f"-I{well_known}",
                f"--python_out={tmp}", f"--pyi_out={tmp}", f"--grpc_python_out={tmp}", *sources]
        if protoc.main(args) != 0:
            raise SystemExit(f"graybox-client: protoc failed on {sources}")
        for f in sorted(Path(tmp, "graybox", "v1").iterdir()):
            text = re.sub(r"^from graybox\.v1 import ", "from . import ", f.read_text(), flags=re.M)
            (out / f.name).write_text(text)


class BuildPy(build_py):
    def run(self):
        if not self.editable_mode:
            # pip builds in place, so build/ outlives a build: start clean, or a module
            # deleted from the source would still be shipped.
            shutil.rmtree(Path(self.build_lib) / PKG, ignore_errors=True)
        super().run()
        # Editable installs import from the source tree, so the stubs go there (gitignored).
        generate(HERE / PKG if self.editable_mode else Path(self.build_lib) / PKG)


class Sdist(sdist):
    def make_release_tree(self, base_dir, files):
        super().make_release_tree(base_dir, files)
        copy_protos(Path(base_dir) / PKG / "proto")


setup(cmdclass={"build_py": BuildPy, "sdist": Sdist})
