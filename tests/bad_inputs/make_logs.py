"""Regenerate the malformed logs of the bad-input corpus (run from the repository root):

    python tests/bad_inputs/make_logs.py
"""

from __future__ import annotations

import json
import random
import sys
from pathlib import Path

from mcap.writer import CompressionType, Writer

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from fuzzynav.config import episode_config_from_dict
from fuzzynav.fuzzy_fast import FastEvaluator
from runners.run import run_episode
from tests.conftest import load_controller, load_scenario
from tests.handmade import rewrite_log

OUT = Path(__file__).resolve().parent / "logs"


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
        ch = w.register_channel("/robot/state", "json", 0)
        w.add_message(ch, 0, json.dumps({"step": 0}).encode(), 0)
        w.finish()
    def drop_x(topic, msg):  # a fuzzynav log whose /robot/state message at step 3 lacks x_cm
        if topic == "/robot/state" and msg["step"] == 3:
            msg.pop("x_cm")

    rewrite_log(good, OUT / "message_off_schema.mcap", drop_x)
    good.unlink()


if __name__ == "__main__":
    main()
