"""Regenerate the malformed logs of the bad-input corpus (run from the repository root):

    python tests/bad_inputs/make_logs.py

Each log is a valid episode log with one thing wrong; ``logs/cases.yaml`` says what the analysis and
``runners.replay`` must answer for each (tests/test_bad_logs.py). The damaged-byte cases are made from a log
written by the Foxglove SDK's writer, which records the data-section and summary CRCs; the re-written ones
through the ``mcap`` library's writer (chunk CRCs only), as a hand-edited log would be.
"""

from __future__ import annotations

import json
import random
import struct
import sys
from pathlib import Path

from mcap.writer import CompressionType, Writer

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from fuzzynav.config import episode_config_from_dict
from fuzzynav.controller.fuzzy_fast import FastEvaluator
from runners.run import run_episode
from tests.conftest import load_controller, load_scenario
from tests.handmade import register_topic
from tests.log_surgery import record_offsets, rewrite

OUT = Path(__file__).resolve().parent / "logs"
BILLION_LAUGHS = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{c}: &{c} [{', '.join(['*' + p] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi", strict=True)) + "dt: 1.0\n"


def _set(path: str, key: str, value):
    """A message edit: ``key`` of the first message on topic ``path`` whose step is 3 (or the only one)."""
    def edit(topic, index, msg):
        if topic == path and (msg.get("step", 3) == 3):
            msg[key] = value
        return msg
    return edit


def _ragged_tpt(topic, index, msg):
    if topic == "/tpt" and index == 0:
        msg["obstacles_cm"][2] = msg["obstacles_cm"][2][:-1]  # one row with a column fewer
    return msg


def main() -> None:
    OUT.mkdir(exist_ok=True)
    good = OUT / "_good.mcap"
    run_episode(load_scenario("head_on"), FastEvaluator(load_controller("table1")), episode_config_from_dict({}), 0,
                good, "dt: 1.0\n")
    data = good.read_bytes()
    (OUT / "empty.mcap").write_bytes(b"")
    (OUT / "random_bytes.mcap").write_bytes(random.Random(7).randbytes(4096))
    (OUT / "truncated_mid_chunk.mcap").write_bytes(data[: int(len(data) * 0.45)])
    with open(OUT / "no_run_metadata.mcap", "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start()
        ch = register_topic(w, "/robot/state")  # with its schema: only the metadata is missing
        w.add_message(ch, 0, json.dumps({"step": 0}).encode(), 0)
        w.finish()

    def drop_x(topic, index, msg):  # a fuzzynav log whose /robot/state message at step 3 lacks x_cm
        if topic == "/robot/state" and msg["step"] == 3:
            msg.pop("x_cm")
        return msg

    rewrite(good, OUT / "message_off_schema.mcap", message=drop_x)

    # issue 14's cases: one flipped digit in an uncompressed chunk (the chunk CRC no longer matches)
    plain = rewrite(good, OUT / "_plain.mcap", compression=CompressionType.NONE).read_bytes()
    at = plain.index(b'"step":10,"x_cm":') + len(b'"step":10,"x_cm":')
    (OUT / "chunk_crc_digit.mcap").write_bytes(plain[:at] + (b"9" if plain[at:at + 1] != b"9" else b"1")
                                               + plain[at + 1:])
    (OUT / "_plain.mcap").unlink()
    # the metadata record changed in place (outside any chunk: only the data-section CRC covers it)
    at = data.index(b"dt: 1.0")
    (OUT / "data_crc.mcap").write_bytes(data[:at] + b"dt: 2.0" + data[at + 7:])
    # a byte of the summary section changed (the summary CRC in the footer no longer matches)
    footer = next(offset for opcode, offset, _n in record_offsets(data) if opcode == 0x02)
    summary_start = struct.unpack_from("<Q", data, footer + 9)[0]
    (OUT / "summary_crc.mcap").write_bytes(data[:summary_start + 20] + bytes([data[summary_start + 20] ^ 0x10])
                                           + data[summary_start + 21:])
    (OUT / "trailing_bytes.mcap").write_bytes(data + b"junk")
    # re-written logs (valid CRCs) whose metadata or messages are wrong
    rewrite(good, OUT / "config_bad_yaml.mcap", metadata=lambda m: {**m, "config": "dt: [1.0\n"})
    rewrite(good, OUT / "config_dt_zero.mcap", metadata=lambda m: {**m, "config": "dt: 0\n"})
    rewrite(good, OUT / "config_alias_bomb.mcap", metadata=lambda m: {**m, "config": BILLION_LAUGHS})
    rewrite(good, OUT / "h_wait_abc.mcap", metadata=lambda m: {**m, "h_wait": "abc"})
    rewrite(good, OUT / "seed_huge.mcap", metadata=lambda m: {**m, "seed": "1e308"})
    rewrite(good, OUT / "config_missing.mcap", metadata=lambda m: {k: v for k, v in m.items() if k != "config"})
    rewrite(good, OUT / "outcome_unknown.mcap", message=_set("/episode", "outcome", "exploded"))
    rewrite(good, OUT / "x_cm_null.mcap", message=_set("/robot/state", "x_cm", None))
    rewrite(good, OUT / "tpt_ragged.mcap", message=_ragged_tpt)
    good.unlink()


if __name__ == "__main__":
    main()
