"""Hostile files: crafted contents behind valid checksums never crash a reader.

Every reader a command uses (``info``, ``convert``, ``replay``, ``eval-stream``, ``run
--skin replay:``, ``dataset``, ``train --captures``, and ``read_bag`` for ``.mcap`` bags)
either reads a file or refuses it with a one-line ``ValueError`` (``FormatError``) naming
the file: never an ``IndexError``, ``OverflowError``, ``RecursionError``, ``MemoryError``
or ``TypeError`` traceback.  A crafted file (``CRAFTED``, and the byte-level bags here) is
refused by every reader: a reader that accepts one fails
``test_every_reader_refuses_every_crafted_file``.  ``file_kind`` only names a file's kind
from its magic or member names (nothing is loaded), so it may name a crafted file's kind;
it must not crash on one.  One reader (``recording.files``) decides what a file is, so
every command reports the same line for the same bad file.  The bags crafted message by
message (bad headers, images, times, documents) are ``test_recording_bag``'s hostile bags.
"""

from __future__ import annotations

import contextlib
import json
import struct
import tempfile
from pathlib import Path

import numpy as np
import pytest
from crafted_files import (
    CRAFTED,
    document,
    frames_payload,
    header,
    npy,
    npy_header,
    npz,
    record,
    stream_members,
    wsrec,
)
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.recording.bag import MCAP_MAGIC, read_bag
from wovenskin.recording.documents import decode_document
from wovenskin.recording.files import file_kind, read_any, read_captures, read_stream
from wovenskin.recording.formats import read_labelled_captures, read_labelled_stream
from wovenskin.recording.inspect import convert_file, describe_file
from wovenskin.recording.native import read_recording
from wovenskin.recording.records import MAGIC, RecordType
from wovenskin.recording.replay import ReplaySource
from wovenskin.recording.untrusted import NOT_OURS, FormatError, load_npz


def _convert_npz(path: Path) -> object:
    return convert_file(path, path.with_name(path.name + ".out.npz"), overwrite=True)


def _convert_wsrec(path: Path) -> object:
    return convert_file(path, path.with_name(path.name + ".out.wsrec"), overwrite=True)


READERS = {
    "read_recording": read_recording,
    "read_labelled_stream": read_labelled_stream,
    "read_labelled_captures": read_labelled_captures,
    "read_bag": read_bag,
    "read_any": read_any,
    "read_stream": read_stream,
    "read_captures": read_captures,
    "replay": lambda p: ReplaySource(p, speed=0),
    "describe_file": describe_file,
    "convert to npz": _convert_npz,
    "convert to wsrec": _convert_wsrec,
}
"""Every function that reads a file's contents: each must refuse every crafted file."""
SNIFFERS = {"file_kind": file_kind}
"""Functions that only name a file's kind (magic, member names): one line or a kind."""
BAG_MAGIC_THEN_ZEROS = MCAP_MAGIC + bytes(100)
HOSTILE = {
    **CRAFTED,
    "magic then zeros.mcap": BAG_MAGIC_THEN_ZEROS,
    "magic then random.mcap": MCAP_MAGIC + bytes(range(256)) * 2,
    "random bytes.mcap": bytes(range(256)) * 4,
    "empty.mcap": b"",
    "a bag named npz.npz": BAG_MAGIC_THEN_ZEROS,
    "a bag named wsrec.wsrec": BAG_MAGIC_THEN_ZEROS,
}
"""The crafted files and the byte-level crafted bags (name -> bytes)."""


def outcome(reader, path: Path) -> str | None:
    """None when ``reader`` accepts ``path``, else its one-line refusal; any exception
    other than ``ValueError`` (or a message of several lines) fails the test."""
    try:
        reader(path)
    except ValueError as exc:
        message = str(exc)
        assert "\n" not in message and message.strip(), repr(message)
        return message
    return None


@pytest.mark.parametrize("name", sorted(HOSTILE))
@pytest.mark.parametrize("reader", sorted(READERS))
def test_every_reader_refuses_every_crafted_file(tmp_path, name, reader):
    path = tmp_path / name
    path.write_bytes(HOSTILE[name])
    refusal = outcome(READERS[reader], path)
    assert refusal is not None, f"{reader} accepted the crafted file {name!r}"
    assert str(path) in refusal, refusal  # the line names the file


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_naming_a_crafted_files_kind_never_crashes(tmp_path, name):
    path = tmp_path / name
    path.write_bytes(HOSTILE[name])
    for sniff in SNIFFERS.values():
        try:
            kind = sniff(path)
        except ValueError as exc:
            assert "\n" not in str(exc) and str(path) in str(exc), repr(str(exc))
        else:
            assert kind in ("recording", "stream", "captures")


@pytest.mark.parametrize("name", sorted(CRAFTED))
def test_the_commands_readers_refuse_every_crafted_file(tmp_path, name):
    path = tmp_path / name
    path.write_bytes(CRAFTED[name])
    refusal = outcome(READERS["replay"], path)
    assert refusal is not None and str(path) in refusal


def test_the_hostile_probe_gets_the_reasons(tmp_path):
    """The probe's cases of issue 13, each with a reason a user can act on."""
    expected = {
        "array index out of range.wsrec": "reference to array 3, but there are 0",
        "shape 1e400.wsrec": "array shape [inf] is not a list of sizes",
        "huge shape.wsrec": "the record does not hold",
        "deep json header.wsrec": "nested deeper than 64 levels",
        "wrong types in header.wsrec": "info.rows must be an integer",
        "npy 364 TiB.npz": "declares shape (1048576, 1048576, 100) of float32",
        "npy object dtype.npz": "pickled",
        "deep metadata json.npz": "nested deeper than 64 levels",
        "random bytes.bin": NOT_OURS,
        "empty.npz": "empty file",
        "cut zip.npz": "damaged .npz",
    }
    for name, words in expected.items():
        path = tmp_path / name
        path.write_bytes(CRAFTED[name])
        with pytest.raises(FormatError) as excinfo:
            read_any(path)
        assert words in str(excinfo.value), (name, str(excinfo.value))


def test_a_member_is_never_allocated_before_its_size_is_checked(tmp_path, monkeypatch):
    """The 364 TiB member is refused from its header: np.load is never asked."""
    monkeypatch.setattr(np, "load", lambda *a, **k: pytest.fail("np.load was called"))
    path = tmp_path / "huge.npz"
    path.write_bytes(CRAFTED["npy 364 TiB.npz"])
    with pytest.raises(FormatError, match="holds 0 bytes"):
        read_labelled_stream(path)


def test_npz_members_read_back_exactly(tmp_path):
    """The member reader that replaced np.load returns the same, writable, arrays."""
    arrays = {
        "frames": np.arange(24, dtype=np.uint16).reshape(2, 3, 4),
        "fortran": np.asfortranarray(np.arange(6.0).reshape(2, 3)),
        "big_endian": np.arange(3, dtype=">f8"),
        "text": np.array(["a", "bcd"]),
        "scalar": np.float64(2.5),
    }
    for compress in (False, True):
        path = tmp_path / f"x{compress}.npz"
        path.write_bytes(npz({k: npy(np.asarray(v)) for k, v in arrays.items()}, compress))
        loaded = load_npz(path)
        for key, value in arrays.items():
            assert loaded[key].dtype == np.asarray(value).dtype
            np.testing.assert_array_equal(loaded[key], value)
        loaded["frames"][0, 0, 0] = 7  # writable, as np.load's were


def test_every_command_names_a_bad_file_the_same_way(tmp_path):
    """info, convert, replay and eval-stream: the same line for the same random bytes."""
    cli = CliRunner()
    path = tmp_path / "junk.npz"
    path.write_bytes(CRAFTED["random bytes.bin"])
    lines = set()
    for args in (
        ["info", str(path)],
        ["convert", str(path), str(tmp_path / "out.npz")],
        ["convert", str(path), str(tmp_path / "out.wsrec")],
        ["replay", str(path)],
        ["eval-stream", str(path)],
    ):
        result = cli.invoke(app, args)
        assert result.exit_code == 2, (args, result.output)
        assert "Traceback" not in result.output
        lines.add(" ".join(result.output.split()))
    assert len(lines) == 1, lines
    assert NOT_OURS in lines.pop()


def test_a_recording_read_as_captures_says_what_it_is(tmp_path):
    path = tmp_path / "r.wsrec"
    path.write_bytes(wsrec(header(), (RecordType.FRAMES, frames_payload())))
    with pytest.raises(FormatError, match="holds a .wsrec recording, not labelled captures"):
        read_captures(path)
    with pytest.raises(FormatError, match="is a .wsrec recording, not an .npz"):
        read_labelled_stream(path)


# ----------------------------------------------------------------------------- fuzzing

JSON_LEAVES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
)
JSON_VALUES = st.recursive(
    JSON_LEAVES,
    lambda children: st.one_of(
        st.lists(children, max_size=4),
        st.dictionaries(
            st.sampled_from(
                [
                    "rows",
                    "cols",
                    "sample_rate_hz",
                    "info",
                    "label",
                    "start_s",
                    "end_s",
                    "t",
                    "stream",
                    "kind",
                    "extra",
                    "__wsrec_array__",
                    "dtype",
                    "shape",
                    "x",
                ]
            ),  # fmt: skip
            children,
            max_size=4,
        ),
    ),
    max_leaves=12,
)
ARRAY_SPECS = st.lists(
    st.one_of(
        JSON_VALUES,
        st.fixed_dictionaries(
            {
                "dtype": st.sampled_from(["<f4", "<i8", "|b1", "|O", "<U3", "V8", "f4,f4", "x"]),
                "shape": st.lists(
                    st.one_of(st.integers(-2, 2**63), st.floats(), st.text(max_size=2)),
                    max_size=3,
                ),
            }
        ),
    ),
    max_size=3,
)
FUZZ = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _check_all_readers(data: bytes, suffix: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"fuzz{suffix}"
        path.write_bytes(data)
        for reader in (*READERS.values(), *SNIFFERS.values()):
            outcome(reader, path)


@FUZZ
@given(doc=JSON_VALUES, specs=ARRAY_SPECS, tail=st.binary(max_size=40), body=st.booleans())
def test_fuzzed_wsrec_documents_never_crash_a_reader(doc, specs, tail, body):
    """Any JSON document, any array specs, any trailing bytes, behind valid CRCs: as the
    HEADER, or as LABEL/ANNOTATION/CALIBRATION/FOOTER records after a good header."""
    text = json.dumps({"arrays": specs, "doc": doc})
    payload = document(text, tail)
    with contextlib.suppress(ValueError):  # a one-line ValueError is the only way to fail
        decode_document(payload)
    if body:
        records = [(RecordType.FRAMES, frames_payload())]
        records += [(rtype, payload) for rtype in (3, 4, 5, 6)]
        data = wsrec(header(), *records)
    else:
        data = wsrec(payload, (RecordType.FRAMES, frames_payload()))
    _check_all_readers(data, ".wsrec")


@FUZZ
@given(
    member=st.sampled_from(["frames", "t", "sample_rate_hz", "event_labels", "lengths"]),
    shape=st.lists(st.integers(0, 2**40), max_size=4).map(tuple),
    dtype=st.sampled_from(["<f4", "<f8", "<i8", "<U4", "|b1", ">f4", "|u1"]),
    extra=st.binary(max_size=64),
    version=st.sampled_from([1, 2]),
    compress=st.booleans(),
)
def test_fuzzed_npy_members_never_crash_a_reader(member, shape, dtype, extra, version, compress):
    """A member whose header declares any shape and dtype, followed by any bytes."""
    members = {**stream_members(), member: npy_header(shape, dtype, version) + extra}
    _check_all_readers(npz(members, compress), ".npz")


@FUZZ
@given(data=st.data())
def test_fuzzed_bytes_of_valid_files_never_crash_a_reader(data):
    """Valid files with bytes overwritten anywhere (checksums recomputed for .wsrec
    documents, zip members rebuilt for .npz): recovery or one line, never a crash."""
    if data.draw(st.booleans(), label="wsrec"):
        good = header()
        at = data.draw(st.integers(0, len(good) - 1), label="at")
        junk = data.draw(st.binary(min_size=1, max_size=8), label="junk")
        mutated = good[:at] + junk + good[at + len(junk) :]
        _check_all_readers(wsrec(mutated, (RecordType.FRAMES, frames_payload())), ".wsrec")
        return
    members = stream_members()
    key = data.draw(st.sampled_from(sorted(members)), label="member")
    raw = members[key]
    at = data.draw(st.integers(0, len(raw) - 1), label="at")
    junk = data.draw(st.binary(min_size=1, max_size=8), label="junk")
    members[key] = raw[:at] + junk + raw[at + len(junk) :]
    _check_all_readers(npz(members), ".npz")


def test_a_truncated_recording_still_reads(tmp_path):
    """The hardening keeps recovery: a cut-off FRAMES record is dropped with a warning."""
    data = wsrec(header(), (RecordType.FRAMES, frames_payload()), (RecordType.FRAMES, b"x" * 9))
    path = tmp_path / "cut.wsrec"
    path.write_bytes(data[:-5])
    recording = read_recording(path)
    assert recording.frames.shape == (3, 2, 2) and recording.warnings
    assert data.startswith(MAGIC) and struct.calcsize("<I") == 4
    assert record(1, b"")[:4] == b"\xa7WR^"
