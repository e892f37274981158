"""The README's claim that graybox_native's calls are the gRPC client's without the model id,
held to the proto and the client: every field of every request message of graybox.v1.Dynamics
has a keyword on the native module's method of that call, or a row in the README's table of
"options with no keyword in the module" with its reason; the module's keywords are the
client's (names and defaults); and the table names no option that has since got a keyword."""

import inspect
import re
from pathlib import Path

import graybox_client
import pytest

import inference_answers as ia
from graybox_client import Client, pb

graybox_native = pytest.importorskip("graybox_native")

EVERY_CALL = "every call"


def _norm(name: str) -> str:
    """A proto field's name as a keyword's: `x_bar` is `xbar`, `q` is `Q`."""
    return name.replace("_", "").lower()


def _snake(rpc: str) -> str:
    return re.sub(r"(?<!^)(?=[A-Z])", "_", rpc).lower()


def requests() -> dict[str, list[str]]:
    """RPC name → its request message's fields, from the generated descriptors."""
    service = pb.DESCRIPTOR.services_by_name["Dynamics"]
    return {m.name: [f.name for f in m.input_type.fields] for m in service.methods}


def params(function) -> dict[str, inspect.Parameter]:
    """A method's parameters but self (and the client's model id)."""
    ps = inspect.signature(function).parameters
    return {k: p for k, p in ps.items() if k not in ("self", "model_id")}


def native_keywords() -> dict[str, set[str]]:
    """RPC name → the normalized keywords of the module's method of that call (none when it
    has no such method)."""
    out = {}
    for rpc in requests():
        method = getattr(graybox_native.Model, _snake(rpc), None)
        out[rpc] = {_norm(k) for k in params(method)} if callable(method) else set()
    return out


def readme_exemptions() -> dict[tuple[str, str], str]:
    """(call, option) → why, from the README's table in "In your controller's process"."""
    text = (ia.ROOT / "README.md").read_text()
    section = text.split("### In your controller's process", 1)[1].split("\n## ", 1)[0]
    head = re.search(r"^\| call \| option \| why[^\n]*\n\|[-| ]+\|\n((?:\|[^\n]*\n)+)",
                     section, re.M)
    assert head, "README: no table of options with no keyword in the module"
    out = {}
    for row in head.group(1).splitlines():
        call, options, why = (c.strip() for c in row.strip().strip("|").split("|"))
        assert why, f"README: no reason given for {options} of {call}"
        for option in re.findall(r"`([^`]+)`", options):
            out[(call, option)] = why
    return out


def missing(keywords: dict[str, set[str]], exempt: dict[tuple[str, str], str]) -> list[str]:
    """Every request field with neither a keyword nor a README row, as "Rpc.field"."""
    return [f"{rpc}.{field}" for rpc, fields in requests().items() for field in fields
            if _norm(field) not in keywords[rpc]
            and (rpc, field) not in exempt and (EVERY_CALL, field) not in exempt]


def test_every_request_option_has_a_keyword_or_a_reason():
    assert missing(native_keywords(), readme_exemptions()) == []


def test_the_check_names_any_keyword_the_module_loses():
    """Without each of the module's keywords in turn, the check fails naming that option:
    the test above would catch a keyword removed from the module."""
    keywords, exempt = native_keywords(), readme_exemptions()
    checked, listed = 0, 0
    for rpc, fields in requests().items():
        for field in fields:
            if _norm(field) in keywords[rpc]:
                fewer = dict(keywords, **{rpc: keywords[rpc] - {_norm(field)}})
                assert missing(fewer, exempt) == [f"{rpc}.{field}"], (rpc, field)
                checked += 1
            else:
                listed += 1
    # Every option is one or the other; today 36 have keywords (Plan's 19 among them).
    assert checked >= 36 and checked + listed == sum(map(len, requests().values()))


def test_the_readme_lists_only_options_that_have_no_keyword():
    requested = requests()
    keywords = native_keywords()
    for (call, option), why in readme_exemptions().items():
        if call == EVERY_CALL:
            assert any(option in fields for fields in requested.values()), option
            assert all(_norm(option) not in keywords[rpc] for rpc, fields in requested.items()
                       if option in fields), f"{option} has a keyword now: drop its row"
        else:
            assert option in requested.get(call, []), f"README: {call} has no option {option}"
            assert _norm(option) not in keywords[call], \
                f"README: {call}.{option} has a keyword now: drop its row"


# The client's calls that the module answers, by the same name.
SHARED = ["predict", "rollout", "linearize", "tvlqr", "plan", "energy"]


def test_the_modules_keywords_and_defaults_are_the_clients():
    exempt = readme_exemptions()
    rpc_of = {_snake(rpc): rpc for rpc in requests()}
    for name in SHARED:
        theirs = params(getattr(Client, name))
        ours = params(getattr(graybox_native.Model, name))
        listed = {o for (call, o) in exempt if call in (rpc_of[name], EVERY_CALL)}
        assert set(theirs) - listed == set(ours), (name, sorted(theirs), sorted(ours))
        for k, p in ours.items():
            q = theirs[k]
            # The client requires some arguments the module may leave out (u: a model with
            # no inputs); where both have a default it is the same.
            if p.default is not p.empty and q.default is not q.empty:
                assert p.default == q.default, (name, k, p.default, q.default)


def test_both_packages_install_their_type_information():
    """PEP 561: what a caller's type checker reads (scripts/test.sh runs mypy --strict on the
    examples with both installed) is in the installed packages, not only in the checkout."""
    client, native = Path(graybox_client.__file__).parent, Path(graybox_native.__file__).parent
    for path in (client / "py.typed", native / "py.typed", native / "_native.pyi"):
        assert path.is_file(), f"{path} is not installed"
