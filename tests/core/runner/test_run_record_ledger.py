"""A recording is checked against the publication ledger a simulator wrote into its run record
(tb4.runner.mcap_record.ledger_in_record): a record that is missing, broken or hand-edited gives no ledger (the check
falls back to sequence numbers alone), never an exception in `tb4 run`'s shutdown."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tb4.runner.mcap_record import ledger_in_record

pytestmark = pytest.mark.core

PUBLISHED = {"/plan": {"010f": 65}}
FIRST_SENT = {"/plan": {"010f": 1795923191358169103}}


def test_both_sections_are_read_from_one_record(tmp_path: Path) -> None:
    record = tmp_path / "run.json"
    record.write_text(json.dumps({"summary": {"published": PUBLISHED, "first_sent_ns": FIRST_SENT}}))
    assert ledger_in_record(record) == (PUBLISHED, FIRST_SENT)


def test_a_record_without_first_send_times_still_gives_its_counts(tmp_path: Path) -> None:
    record = tmp_path / "run.json"  # a simulator from before first_sent_ns, or a hand-trimmed record
    record.write_text(json.dumps({"summary": {"published": PUBLISHED}}))
    assert ledger_in_record(record) == (PUBLISHED, None)


@pytest.mark.parametrize(
    "text",
    [
        "",  # written as the simulator died
        '{"summary": {"published": {"/plan": {"010f": 6',  # cut short
        "[1, 2, 3]",
        '{"summary": null}',
        '{"summary": [1, 2]}',
        '{"summary": {"published": "all of it", "first_sent_ns": [1, 2]}}',
        '{"summary": {"published": NaN, "first_sent_ns": 1e999}}',
        "\x00\xff" * 10,
    ],
    ids=["empty", "truncated", "list", "null-summary", "list-summary", "wrong-types", "nan-inf", "binary"],
)
def test_a_broken_record_gives_no_ledger(tmp_path: Path, text: str) -> None:
    record = tmp_path / "run.json"
    record.write_text(text, encoding="utf-8", errors="surrogateescape")
    assert ledger_in_record(record) == (None, None)


def test_a_missing_or_unreadable_record_gives_no_ledger(tmp_path: Path) -> None:
    assert ledger_in_record(tmp_path / "absent.json") == (None, None)
    assert ledger_in_record(tmp_path) == (None, None)  # a directory where the record should be
