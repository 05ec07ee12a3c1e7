"""benchmarks.throughput: the model's arithmetic on parts chosen by hand (no timing)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from benchmarks.throughput import (
    GB,
    PAGE_CACHE,
    Parts,
    Storage,
    duration,
    fractional,
    predict,
    predicted_cpu,
    scale_table,
)

# 1024² frames: 50 ms each, 1 s per sequence, 1 MB read and 100 B written per frame, 200 kB
# per sequence; 2 s to start the workers, 0.5 s dispatch, 1 ms at the scheduler per sequence
PARTS = Parts(frame_s={1024: 0.05}, seq_s={1024: 1.0}, in_bytes={1024: 1e6},
              out_frame_bytes={1024: 100.0}, out_seq_bytes={1024: 2e5}, start_s=2.0, task_s=0.5,
              sched_s=0.001)
SHARED = Storage(shared_Bps=10 * GB, node_Bps=1 * GB, latency_s=0.001, stream_Bps=1 * GB)


def test_one_node_is_bound_by_compute():
    p = predict(PARTS, frames=1_000_000, side=1024, seq_len=1000, nodes=1, cores=32, storage=SHARED)
    assert (p.sequences, p.slots, p.busy, p.waves) == (1000, 32, 32, 32)  # ceil(1000 / 32)
    # a sequence: 1 + 0.5 + 1000 * (0.05 + 0.001 + 1e6 / 1e9) = 53.5 s
    assert p.seq_time == pytest.approx(53.5)
    assert p.compute == pytest.approx(32 * 1000 * 0.05)
    assert p.overhead == pytest.approx(32 * 1.5)
    assert p.fetch == pytest.approx(32 * 1000 * 0.002)
    assert p.makespan == pytest.approx(32 * 53.5) == pytest.approx(p.compute + p.overhead + p.fetch)
    # 1e6 frames * (1e6 + 100) B + 1000 * 2e5 B over min(10 GB/s, 1 node * 1 GB/s)
    assert p.read == pytest.approx((1e6 * (1e6 + 100) + 1000 * 2e5) / 1e9)
    assert p.sched == pytest.approx(1.0)
    assert p.wall == pytest.approx(2.0 + 32 * 53.5)
    assert p.bound == "compute"


def test_more_nodes_than_sequences_leaves_one_sequence_or_the_storage():
    p = predict(PARTS, frames=1_000_000, side=1024, seq_len=1000, nodes=100, cores=32,
                storage=Storage(shared_Bps=1000 * GB, node_Bps=1 * GB, latency_s=0.001,
                                stream_Bps=1 * GB))
    assert (p.busy, p.waves) == (1000, 1)
    assert p.read == pytest.approx(1.0003e12 / 100e9)  # the nodes' network: 100 GB/s
    assert p.wall == pytest.approx(2.0 + 53.5) and p.bound == "sequence length"
    # the same on a 10 GB/s shared file system: 100 s of reading
    q = predict(PARTS, frames=1_000_000, side=1024, seq_len=1000, nodes=100, cores=32, storage=SHARED)
    assert q.read == pytest.approx(1.0003e12 / 10e9)
    assert q.wall == pytest.approx(2.0 + q.read) and q.bound == "storage"
    # ... and on 10 nodes of a 1 GB/s network each, the network is the limit only when
    # compute is faster: here 4 rounds of 53.5 s = 214 s against 100 s of reading
    r = predict(PARTS, frames=1_000_000, side=1024, seq_len=1000, nodes=10, cores=32, storage=SHARED)
    assert r.waves == 4 and r.bound == "compute"
    fast = dataclasses.replace(PARTS, frame_s={1024: 0.001})
    s = predict(fast, frames=1_000_000, side=1024, seq_len=1000, nodes=10, cores=32,
                storage=Storage(shared_Bps=1000 * GB, node_Bps=1 * GB, latency_s=0.0,
                                stream_Bps=math.inf))
    assert s.read == pytest.approx(1.0003e12 / 10e9) and s.bound == "node network"


def test_many_short_sequences_are_bound_by_the_scheduler():
    p = predict(PARTS, frames=1_000_000, side=1024, seq_len=10, nodes=1000, cores=32, storage=PAGE_CACHE)
    assert p.sequences == 100_000 and p.waves == 4  # ceil(100000 / 32000)
    assert p.sched == pytest.approx(100.0)
    assert p.makespan == pytest.approx(4 * (1.5 + 10 * 0.05))
    assert p.read == 0.0 and p.fetch == 0.0  # the page cache: no storage term
    assert p.wall == pytest.approx(102.0) and p.bound == "scheduler"


def test_a_last_short_sequence_counts_as_one():
    p = predict(PARTS, frames=1001, side=1024, seq_len=1000, nodes=1, cores=1)
    assert p.sequences == 2 and p.waves == 2
    with pytest.raises(ValueError):
        predict(PARTS, frames=10, side=1024, seq_len=0, nodes=1, cores=1)


def test_the_check_on_a_laptop():
    parts = Parts(frame_s={256: 0.01}, seq_s={256: 0.2}, in_bytes={256: 5e4},
                  out_frame_bytes={256: 100.0}, out_seq_bytes={256: 2e5}, start_s=0.4, task_s=0.0)
    # 4 sequences of 60 frames: 0.8 s each; 1 worker 4 rounds, 2 workers 2
    one = predict(parts, frames=240, side=256, seq_len=60, nodes=1, cores=1)
    two = predict(parts, frames=240, side=256, seq_len=60, nodes=1, cores=2)
    assert one.wall == pytest.approx(0.4 + 4 * 0.8) and two.wall == pytest.approx(0.4 + 2 * 0.8)
    # on 1.5 free cores the work (3.2 s) takes 2.13 s; on 8 no less than one sequence
    assert fractional(parts, sequences=4, seq_len=60, side=256, cores=1.5) == pytest.approx(0.4 + 3.2 / 1.5)
    assert fractional(parts, sequences=4, seq_len=60, side=256, cores=8) == pytest.approx(0.4 + 0.8)
    # CPU: each worker started (0.4 s) plus the work
    assert predicted_cpu(parts, sequences=4, seq_len=60, side=256, workers=2) == pytest.approx(0.8 + 3.2)
    assert predicted_cpu(parts, sequences=1, seq_len=60, side=256, workers=2) == pytest.approx(0.4 + 0.8)


def test_parts_round_trip_through_json_and_the_table_reads():
    import json

    back = Parts.from_json(json.loads(json.dumps(PARTS.to_json())))
    assert back == PARTS
    table = scale_table(PARTS, frames=1_000_000, side=1024, seq_len=1000, nodes=[1, 100], cores=32,
                        storage=SHARED)
    lines = table.splitlines()
    assert len(lines) == 4 and lines[2].startswith("| 1 | 32 / 32 | 32 |")
    assert lines[3].endswith("| storage |")
    assert [duration(s) for s in (42, 210, 7560, 3 * 86400)] == ["42 s", "3.5 min", "2.1 h", "3 d"]
