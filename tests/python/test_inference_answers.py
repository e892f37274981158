"""The service answers the recorded inference calls (tests/fixtures/inference/answers.json)
exactly as it did when they were recorded, bit for bit: Predict, Rollout, Linearize, Tvlqr and
Plan (iLQR and direct collocation) for an MVF and an older-format MVF, a W-B cart-pole, a
formula template's W-B, a UR5 with a residual force network, and an ensemble. Moving the
inference code (to a crate of its own, behind the C library) must not change one bit of an
answer; a change of the math that does is a new record, made on purpose by
scripts/inference_fixtures.sh after deleting the old one.

With GRAYBOX_WRITE_INFERENCE=1 (what the script sets) the models missing from the record are
recorded instead of checked, and the recorded answers that lack the max_abs_z their call
answers get it."""

import json
import os

import pytest

import inference_answers as ia


def _upload(server, path) -> str:
    status, m = server.rest.post("/v1/models", raw=path.read_bytes())
    assert status in (200, 201), m
    return m["id"]


def test_inference_answers_are_the_recorded_ones(server, client):
    if os.environ.get("GRAYBOX_WRITE_INFERENCE") == "1":
        have = ia.load() if ia.ANSWERS.exists() else {}
        new = ia.record(client, lambda p: _upload(server, p), skip=set(have))
        completed = ia.complete(client, lambda p: _upload(server, p), have)
        ia.write({**have, **new})
        pytest.skip(f"recorded {sorted(new)}, added z to {completed}")
    record = ia.load()
    assert sorted(record) == sorted(ia.MODELS), "every model has its record"
    for name, entry in record.items():
        model_id = _upload(server, ia.ROOT / entry["file"])
        for call in entry["calls"]:
            got = ia.answer(client, model_id, call)
            # json.dumps prints each float in its shortest round-trip form, so equal text is
            # equal bits (and tells −0.0 from 0.0).
            where = ia.first_difference(got, call["answer"])
            assert not where, f"{name} {call['rpc']} {call.get('method', '')}{where}"
