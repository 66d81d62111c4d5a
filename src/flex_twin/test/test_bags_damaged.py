"""Damaged bags (issue 23, defect 6): a truncated, random-byte, partly zeroed or empty .mcap
and a missing or unreadable metadata.yaml. ``bag info`` / ``play`` / ``read_bag`` either
stop with one line and rc 2 (nothing readable) or read everything intact and warn with one
line naming the lost byte range, log-time range and the message counts against
metadata.yaml; never a traceback, never a silent loss or a corrupted message.

Bags written by :class:`BagWriter` carry chunk CRCs (the golden bags, written before, do not:
damage there is found from the record framing and the message index, a damaged payload
inside a CRC-less chunk cannot be detected).
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import warnings

import pytest
from sensor_msgs.msg import JointState

from flex_twin.bag_cli import add_bag_parsers
from flex_twin.bags import BagDamageWarning, BagError, BagWriter, bag_info, iter_raw, read_bag

from flex_model.command import run_command

N = 2000
DT_NS = 10_000_000  # 100 Hz, a 20 s bag
T0_NS = 1_000_000_000


def _msg(i):
    m = JointState(name=["joint1", "joint2"], position=[0.1 * i, -2.0], velocity=[], effort=[])
    m.header.stamp.sec = i
    return m


@pytest.fixture(scope="module")
def good_bag(tmp_path_factory):
    """A 20 s, 2000-message bag in 40 chunks of 50 messages (the recorder's 0.5 s chunks)."""
    path = tmp_path_factory.mktemp("good") / "bag"
    with BagWriter(path) as writer:
        for i in range(N):
            writer.write("/js", _msg(i), T0_NS + DT_NS * i)
            if i % 50 == 49:
                writer.flush()
    return path


def _copy(src, tmp_path, damage=None):
    dst = tmp_path / "bag"
    shutil.copytree(src, dst)
    mcap = next(dst.glob("*.mcap"))
    if damage is not None:
        mcap.write_bytes(damage(mcap.read_bytes()))
    return dst


def _zero_middle(data, n=4096, fill=bytes):
    mid = len(data) // 2
    return data[:mid] + fill(n) + data[mid + n:]


def _read(path):
    """(messages as (topic, t_ns, bytes), warning texts)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rows = [(topic, t, data) for topic, _, t, data, _ in iter_raw(path)]
    return rows, [str(w.message) for w in caught if w.category is BagDamageWarning]


def _cli(argv, capsys):
    parser = argparse.ArgumentParser(prog="flex-twin")
    add_bag_parsers(parser.add_subparsers(dest="command", required=True))
    rc = run_command(parser.parse_args(argv))
    out, err = capsys.readouterr()
    return rc, out, err.strip().splitlines()


def test_good_bag_reads_without_warning(good_bag, capsys):
    rows, warned = _read(good_bag)
    assert len(rows) == N and not warned
    rc, _, err = _cli(["bag", "info", str(good_bag)], capsys)
    assert rc == 0 and err == []


def test_truncated_bag_reads_the_intact_part_and_names_the_loss(good_bag, tmp_path, capsys):
    bag = _copy(good_bag, tmp_path, lambda d: d[:len(d) // 2])
    rows, (warning,) = _read(bag)
    full, _ = _read(good_bag)
    assert 0.4 * N < len(rows) < 0.6 * N
    assert rows == full[:len(rows)]  # the intact head, in order, unchanged
    assert "truncated" in warning and "no footer" in warning
    assert f"read {len(rows)} of {N} message(s) listed in metadata.yaml" in warning
    last = rows[-1][1] * 1e-9
    assert f"messages after log time {last:.3f} s missing" in warning
    assert f"the bag ends at {(T0_NS + DT_NS * (N - 1)) * 1e-9:.3f} s" in warning
    rc, out, err = _cli(["bag", "info", str(bag)], capsys)
    assert rc == 0 and len(err) == 1 and err[0].startswith("flex-twin: warning: ")
    assert f"messages:  {len(rows)}" in out


@pytest.mark.parametrize("fill", [bytes, os.urandom], ids=["zeroed", "random"])
def test_damaged_4kb_region_loses_only_its_chunks_and_says_which(good_bag, tmp_path, capsys,
                                                                 fill):
    bag = _copy(good_bag, tmp_path, lambda d: _zero_middle(d, fill=fill))
    rows, (warning,) = _read(bag)
    full, _ = _read(good_bag)
    assert set(rows) <= set(full)  # no corrupted message passes the CRC check
    assert N - 150 <= len(rows) < N  # 4 KB spans at most 3 chunks of 50 messages
    lost_t = sorted({t for _, t, _ in full} - {t for _, t, _ in rows})
    assert lost_t[-1] - lost_t[0] == DT_NS * (len(lost_t) - 1)  # one contiguous range
    assert "fails its CRC" in warning or "damaged" in warning
    assert f"{lost_t[0] * 1e-9:.3f}" in warning  # the lost log-time range is named
    assert f"read {len(rows)} of {N} message(s)" in warning and f"/js {len(rows)} of {N}" \
        in warning
    rc, _, err = _cli(["bag", "info", str(bag)], capsys)
    assert rc == 0 and len(err) == 1 and "warning" in err[0]


def test_zeroed_region_in_a_golden_bag_without_crcs(repo_root, tmp_path):
    src = repo_root / "test" / "data" / "bags" / "model_lockstep"
    bag = _copy(src, tmp_path, _zero_middle)
    rows, (warning,) = _read(bag)
    full, _ = _read(src)
    assert set(rows) <= set(full) and len(rows) < len(full)
    assert "damaged inside (no CRC)" in warning
    assert f"read {len(rows)} of {len(full)} message(s) listed in metadata.yaml" in warning


@pytest.mark.parametrize("damage, what", [
    (lambda d: b"", "empty file (0 bytes)"),
    (lambda d: os.urandom(len(d)), "not an MCAP file"),
    (lambda d: d[:8], "the file ends after the MCAP header"),
    (lambda d: d[:8] + os.urandom(len(d) - 8), "no intact topic or message"),
], ids=["zero-bytes", "random-bytes", "magic-only", "random-after-magic"])
def test_unreadable_bag_is_one_line_rc_2(good_bag, tmp_path, capsys, damage, what):
    bag = _copy(good_bag, tmp_path, damage)
    with pytest.raises(BagError, match=re.escape(what)):
        list(read_bag(bag))
    for argv in (["bag", "info", str(bag)], ["play", str(bag), "--delay", "0"]):
        rc, out, err = _cli(argv, capsys)
        assert rc == 2 and out == "" and len(err) == 1, (argv, err)
        assert err[0].startswith("flex-twin: error: bag ") and what in err[0]


def test_missing_metadata_reads_the_whole_mcap(good_bag, tmp_path, capsys):
    bag = _copy(good_bag, tmp_path)
    (bag / "metadata.yaml").unlink()
    rows, (warning,) = _read(bag)
    assert rows == _read(good_bag)[0]
    assert "no metadata.yaml" in warning and f"all {N} message(s)" in warning
    with pytest.warns(BagDamageWarning, match="no metadata.yaml"):
        info = bag_info(bag)
    assert info["message_count"] == N and info["topics"][0]["count"] == N
    rc, out, err = _cli(["bag", "info", str(bag)], capsys)
    assert rc == 0 and len(err) == 1 and f"messages:  {N}" in out


def test_renamed_mcap_is_found_without_its_metadata_entry(good_bag, tmp_path):
    bag = _copy(good_bag, tmp_path)
    next(bag.glob("*.mcap")).rename(bag / "renamed.mcap")
    rows, (warning,) = _read(bag)
    assert len(rows) == N and "lists missing file(s) ['bag.mcap']" in warning
    assert f"all {N} message(s) listed in metadata.yaml read" in warning


def test_unreadable_metadata_falls_back_to_the_mcap(good_bag, tmp_path):
    bag = _copy(good_bag, tmp_path)
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    rows, (warning,) = _read(bag)
    assert len(rows) == N and "metadata.yaml unreadable" in warning


def test_counts_short_of_metadata_are_never_silent(good_bag, tmp_path):
    """A cleanly closed .mcap holding fewer messages than metadata.yaml lists (e.g. a file
    replaced by an older one): the shortfall is named per topic."""
    bag = _copy(good_bag, tmp_path)
    meta = (bag / "metadata.yaml").read_text()
    (bag / "metadata.yaml").write_text(meta.replace(f"message_count: {N}",
                                                    f"message_count: {N + 5}"))
    _, (warning,) = _read(bag)
    assert f"/js {N} of {N + 5}" in warning


def test_play_of_a_damaged_bag_plays_the_intact_part_with_a_warning(good_bag, tmp_path,
                                                                    capsys):
    bag = _copy(good_bag, tmp_path, _zero_middle)
    rows, _ = _read(bag)
    rc, out, err = _cli(["play", str(bag), "--rate", "1000", "--delay", "0"], capsys)
    assert rc == 0 and f"published {len(rows)} message(s)" in out
    assert len(err) == 1 and err[0].startswith("flex-twin: warning: ")


def test_cli_subprocess_on_damaged_bags_never_prints_a_traceback(good_bag, tmp_path,
                                                                 repo_root):
    cases = {"truncated": (lambda d: d[:len(d) // 3], 0),
             "random": (lambda d: os.urandom(len(d)), 2),
             "zeroed": (_zero_middle, 0), "empty": (lambda d: b"", 2)}
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(repo_root / "src" / "flex_model"), os.environ.get("PYTHONPATH", "")]))
    for name, (damage, want_rc) in cases.items():
        bag = _copy(good_bag, tmp_path / name, damage)
        proc = subprocess.run([sys.executable, "-m", "flex_twin.bag_cli", "bag", "info",
                               str(bag)], env=env, capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == want_rc, (name, proc.stderr)
        assert len(proc.stderr.splitlines()) == 1 and "Traceback" not in proc.stderr, name
