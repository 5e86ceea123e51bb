"""The checkpoint file: every line checked, damage named and never silently dropped, the
file left as it was unless the user asks for a repair, nothing written before the first
fixed sensor."""

import json

import pytest

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.settings import OptimizeSettings
from headless.checkpoint import NAME, Checkpoint, decode_line, encode_line

HEADER = {
    "scene": "x.blend",
    "scene_fingerprint": "0123456789abcdef",
    "model": {"name": "cam"},
    "settings": OptimizeSettings().to_dict(),
}


def record(n: int) -> dict:
    return {
        "n": n, "x": 1.5 * n, "y": -2.0, "pitch_deg": 30.0, "yaw_deg": 90.0 * n,
        "fitness": 0.25, "epochs": 3, "evaluations": 40, "rng_state": {"s": [n, 7]},
    }  # fmt: skip


def written(tmp_path, n_records: int) -> Checkpoint:
    cp = Checkpoint(tmp_path, HEADER)
    for n in range(1, n_records + 1):
        cp.append(record(n))
    return cp


def test_records_come_back_exactly(tmp_path):
    written(tmp_path, 3)
    lines = (tmp_path / NAME).read_text().splitlines()
    assert len(lines) == 4 and all(set(json.loads(ln)) == {"sha", "data"} for ln in lines)
    assert Checkpoint(tmp_path, HEADER).resume() == [record(1), record(2), record(3)]


def test_nothing_is_written_before_the_first_sensor(tmp_path):
    written(tmp_path, 2)
    before = (tmp_path / NAME).read_bytes()
    Checkpoint(tmp_path, dict(HEADER, scene_fingerprint="ffff"))  # a new run, never fixing one
    assert (tmp_path / NAME).read_bytes() == before


def test_a_line_cut_short_by_a_crash_is_dropped_and_trimmed_at_the_next_append(tmp_path):
    written(tmp_path, 2)
    path = tmp_path / NAME
    whole = path.read_bytes()
    path.write_bytes(whole + encode_line(record(3)).encode()[:25])  # no newline yet
    cut = path.read_bytes()
    cp = Checkpoint(tmp_path, HEADER)
    assert cp.resume() == [record(1), record(2)]
    assert path.read_bytes() == cut  # reading changes nothing
    cp.append(record(3))
    assert path.read_bytes() == whole + encode_line(record(3)).encode()
    assert Checkpoint(tmp_path, HEADER).resume() == [record(1), record(2), record(3)]


def test_a_damaged_middle_line_stops_the_resume_and_leaves_the_file(tmp_path):
    written(tmp_path, 5)
    path = tmp_path / NAME
    lines = path.read_text().splitlines(keepends=True)
    lines[2] = lines[2].replace('"x": 3.0', '"x": 3.5')  # record 2 changed by hand
    assert lines[2] != path.read_text().splitlines(keepends=True)[2]
    path.write_text("".join(lines))
    before = path.read_bytes()
    with pytest.raises(InputError, match=r"line 3 is damaged: checksum does not match.*"
                       r"--resume --repair keeps the 1 record\(s\) before it"):  # fmt: skip
        Checkpoint(tmp_path, HEADER).resume()
    assert path.read_bytes() == before
    assert not (tmp_path / (NAME + ".damaged")).exists()

    # Asked to, it keeps the valid prefix, the whole file saved beside it.
    cp = Checkpoint(tmp_path, HEADER)
    assert cp.resume(repair=True) == [record(1)]
    assert (tmp_path / (NAME + ".damaged")).read_bytes() == before
    assert path.read_bytes() == b"".join(ln.encode() for ln in lines[:2])
    cp.append(record(2))
    assert Checkpoint(tmp_path, HEADER).resume() == [record(1), record(2)]


@pytest.mark.parametrize(
    "line, why",
    [
        (b"\xff\xfe{}\n", "not UTF-8"),
        (b"[1, 2]\n", "not a checkpoint line"),
        (b'{"n": 1, "x": 0}\n', "not a checkpoint line"),
        (b"{not json\n", "not JSON"),
        (b'{"sha": "0", "data": {}}\n', "checksum does not match"),
        (encode_line({"foo": 1}).encode(), "record x must be a number"),
        (encode_line(None).encode(), "a record must be a JSON object"),
        (encode_line(dict(record(1), epochs=2.5)).encode(), "record epochs must be a count"),
        (encode_line(dict(record(1), x=10**400)).encode(), "record x must be finite"),
        (encode_line(record(4)).encode(), "record of sensor 4 where sensor 2 belongs"),
    ],
)
def test_every_kind_of_damaged_record_is_named(tmp_path, line, why):
    written(tmp_path, 1)
    path = tmp_path / NAME
    path.write_bytes(path.read_bytes() + line + encode_line(record(2)).encode())
    before = path.read_bytes()
    with pytest.raises(InputError, match=f"line 3 is damaged: {why}"):
        Checkpoint(tmp_path, HEADER).resume()
    assert path.read_bytes() == before


@pytest.mark.parametrize("header", [[1, 2], "text", None])
def test_a_header_that_is_not_an_object_is_named(tmp_path, header):
    (tmp_path / NAME).write_text(encode_line(header))
    with pytest.raises(InputError, match="line 1 is damaged: the header must be a JSON object"):
        Checkpoint(tmp_path, HEADER).resume()
    with pytest.raises(InputError, match="nothing to keep"):
        Checkpoint(tmp_path, HEADER).resume(repair=True)


def test_nan_never_reaches_the_file():
    with pytest.raises(ValueError):
        encode_line(dict(record(1), fitness=float("nan")))
    assert decode_line(encode_line(record(1)).encode()) == record(1)
