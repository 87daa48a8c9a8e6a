"""AylluLite refuses the transaction requests cleanly (spec/conformance.md "Transactions"):
each vector of spec/vectors/transactions.json decodes to a request of an unknown operation
(its `lite_expect`), and a lite node answers it with an error REPLY, so a coordinator aborts a
plan that names a lite node instead of waiting for it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

import ayllu_lite as al

VECTORS = Path(__file__).resolve().parents[3] / "spec" / "vectors" / "transactions.json"
# Committed with the golden vectors: a missing file fails here, naming it, rather than skipping.
DOC: dict[str, Any] | None = json.loads(VECTORS.read_text(encoding="utf-8"))
CASES = DOC["vectors"] if DOC else []


@pytest.mark.parametrize("vector", CASES, ids=lambda v: str(v["name"]))
def test_a_transaction_request_is_an_unknown_operation_to_lite(vector: dict[str, Any]) -> None:
    expect = vector["lite_expect"]
    d = al.decode(bytes.fromhex(vector["hex"]), vector["team"], None)
    assert d.sender == expect["sender"]
    assert d.seq == expect["seq"]
    assert [al.message_to_json(m) for m in d.messages] == expect["messages"]


def test_a_lite_node_answers_them_with_an_error() -> None:
    node = al.LiteNode(5, 7, bind=("127.0.0.1", 0))
    try:
        for v in CASES:
            (m,) = al.decode(bytes.fromhex(v["hex"]), v["team"], None).messages
            assert isinstance(m, al.Request)
            reply = node._serve(m)
            assert reply.error == "unknown operation", reply
    finally:
        node.close()
