"""Stream CSV and TUM readers/writers, sample checks, and stream-to-state association, with exact numbers."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit.data.association import interpolate_poses, nearest, segment_ids
from fusionkit.data.files import read_csv_header, read_csv_stream, read_tum, write_csv_stream, write_tum
from fusionkit.data.plain_text import plain_csv, plain_table
from fusionkit.data.stream import POSE_COLUMNS, Stream, check_samples
from fusionkit.errors import DataError

SQRT_HALF = np.sqrt(0.5)


def write(tmp_path, name: str, text: str | bytes):
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


# ---------------------------------------------------------------- CSV


def test_csv_reads_header_values_and_skips_comments_and_blank_lines(tmp_path):
    path = write(tmp_path, "wheel.csv", "# wheel encoders\nt, left ,right\n0.0,1.5,-2\n\n# pause\n0.25,3,4e-3\n")
    s = read_csv_stream(path, "wheels")
    assert s.name == "wheels" and s.origin == str(path)
    assert s.columns == ("left", "right")
    np.testing.assert_array_equal(s.t, [0.0, 0.25])
    np.testing.assert_array_equal(s.values, [[1.5, -2.0], [3.0, 0.004]])
    np.testing.assert_array_equal(s.column("right"), [-2.0, 0.004])


def test_csv_with_byte_order_mark_reads_t_column(tmp_path):
    path = write(tmp_path, "excel.csv", "\ufefft,x\n1,2\n2,3\n".encode("utf-8"))
    s = read_csv_stream(path, "s")
    assert s.columns == ("x",)
    np.testing.assert_array_equal(s.t, [1.0, 2.0])


def test_csv_required_columns_present_and_missing(tmp_path):
    path = write(tmp_path, "imu.csv", "# header on line 2\nt,ax,ay\n0,1,2\n")
    assert read_csv_stream(path, "imu", ("ax", "ay")).columns == ("ax", "ay")
    with pytest.raises(DataError) as err:
        read_csv_stream(path, "imu", ("ax", "az", "gz"))
    assert str(err.value) == (f"{path}:2: missing column(s) az, gz; header has t,ax,ay, "
                              "expected at least t,ax,az,gz")


def test_csv_first_column_must_be_t(tmp_path):
    path = write(tmp_path, "a.csv", "time,x\n0,1\n")
    with pytest.raises(DataError) as err:
        read_csv_stream(path, "a")
    assert str(err.value) == (f"{path}:1: first column is 'time'; expected 't' (time in seconds), header was time,x "
                              "(static samples without times: `time: row` on a csv source numbers the rows)")


def test_csv_repeated_or_empty_column_names_are_named_at_the_header_line(tmp_path):
    path = write(tmp_path, "a.csv", "t,x,x,\n0,1,2,3\n")
    with pytest.raises(DataError) as err:
        read_csv_stream(path, "a")
    assert str(err.value) == (f"{path}:1: column name(s) '', 'x' empty or repeated; expected distinct names, "
                              "header was t,x,x,")


def test_csv_row_with_wrong_number_of_columns_names_its_line(tmp_path):
    path = write(tmp_path, "a.csv", "t,x,y\n0,1,2\n# gap\n1,2\n")
    with pytest.raises(DataError) as err:
        read_csv_stream(path, "a")
    assert str(err.value) == f"{path}:4: row has 2 columns; header has 3 (t,x,y)"


def test_csv_non_numeric_cell_names_line_column_and_value(tmp_path):
    path = write(tmp_path, "a.csv", "t,x,y\n0,1,2\n\n1,2,oops\n")
    with pytest.raises(DataError) as err:
        read_csv_stream(path, "a")
    assert str(err.value) == f"{path}:4: column 'y' has 'oops'; expected a number"
    path = write(tmp_path, "b.csv", "t,x\n0,\n")
    with pytest.raises(DataError, match=r"b\.csv:2: column 'x' has ''; expected a number"):
        read_csv_stream(path, "b")


def test_csv_nan_counts_rows_and_reports_first_physical_line(tmp_path):
    # two comment lines and a blank line before the data: line numbers are the file's, not row indices
    path = write(tmp_path, "a.csv", "# c1\n# c2\nt,x\n\n0,1\n1,nan\n2,3\n3,inf\n")
    with pytest.raises(DataError) as err:
        read_csv_stream(path, "a")
    assert str(err.value) == (f"{path}:6: 2 row(s) contain NaN or infinite values (first at line 6); "
                              "expected finite numbers")


def test_csv_timestamps_going_back_count_and_first_line_and_repeated_ones_pass(tmp_path):
    path = write(tmp_path, "a.csv", "t,x\n0,0\n# note\n1,0\n1,0\n0.5,0\n0.7,0\n0.2,0\n")
    with pytest.raises(DataError) as err:
        read_csv_stream(path, "a")
    assert str(err.value) == (f"{path}:6: 2 row(s) have timestamps that go back in time (first at line 6); "
                              "expected non-decreasing t in seconds")
    same = read_csv_stream(write(tmp_path, "b.csv", "t,x\n0,0\n1,0\n1,2\n2,0\n"), "b")
    assert same.repeated_stamps() == (1, 1.0)


@pytest.mark.parametrize("text, message", [
    ("", "empty file; expected a header row starting with 't'"),
    ("# only a comment\n\n", "empty file; expected a header row starting with 't'"),
    ("t,x\n", "no samples (expected at least one data row)"),
])
def test_csv_without_data_rows_says_empty_file_or_no_samples(tmp_path, text, message):
    path = write(tmp_path, "a.csv", text)
    with pytest.raises(DataError) as err:
        read_csv_stream(path, "a")
    assert str(err.value) == f"{path}: {message}"


def test_unreadable_files_say_what_is_wrong(tmp_path):
    with pytest.raises(DataError) as err:
        read_csv_stream(tmp_path / "none.csv", "a")
    assert str(err.value) == f"{tmp_path / 'none.csv'}: file not found"
    (tmp_path / "folder.tum").mkdir()
    with pytest.raises(DataError) as err:
        read_tum(tmp_path / "folder.tum", "a")
    assert str(err.value) == f"{tmp_path / 'folder.tum'}: is a folder; expected a file"
    path = write(tmp_path, "binary.csv", b"t,x\n\xff\xfe\x00\n")
    with pytest.raises(DataError) as err:
        read_csv_stream(path, "a")
    assert str(err.value) == f"{path}:2: cannot read: byte 4 is not UTF-8 text; expected a text file"


def test_csv_header_is_read_without_the_rows_and_its_errors_are_located(tmp_path):
    path = write(tmp_path, "a.csv", "\ufeff# exported by a logger\n\n t , ax,ay\n0,1\n".encode("utf-8"))
    assert read_csv_header(path) == ("ax", "ay")  # data rows are not read (the short row is not noticed)
    path = write(tmp_path, "b.csv", "# c\nx,y\n")
    with pytest.raises(DataError) as err:
        read_csv_header(path)
    assert str(err.value) == (f"{path}:2: first column is 'x'; expected 't' (time in seconds), header was x,y "
                              "(static samples without times: `time: row` on a csv source numbers the rows)")
    path = write(tmp_path, "c.csv", "# only comments\n")
    with pytest.raises(DataError) as err:
        read_csv_header(path)
    assert str(err.value) == f"{path}: empty file; expected a header row starting with 't'"
    path = write(tmp_path, "d.csv", b"# fine\n\xff,t\n")
    with pytest.raises(DataError) as err:
        read_csv_header(path)
    assert str(err.value) == f"{path}:2: cannot read: byte 7 is not UTF-8 text; expected a text file"
    with pytest.raises(DataError) as err:
        read_csv_header(tmp_path / "none.csv")
    assert str(err.value) == f"{tmp_path / 'none.csv'}: file not found"


def test_csv_round_trip_gives_back_the_exact_times_and_values(tmp_path):
    s = Stream("odom", np.array([0.0, 0.1, 0.2]), ("v", "w"), np.array([[1.0, -0.5], [1.25, 0.0], [2e-7, 3.0]]))
    write_csv_stream(tmp_path / "odom.csv", s)
    assert (tmp_path / "odom.csv").read_text().splitlines()[0] == "t,v,w"
    back = read_csv_stream(tmp_path / "odom.csv", "odom")
    assert back.columns == ("v", "w")
    np.testing.assert_array_equal(back.t, s.t)
    np.testing.assert_array_equal(back.values, s.values)


# ---------------------------------------------------------------- TUM


def test_tum_reads_poses_and_normalizes_quaternions(tmp_path):
    path = write(tmp_path, "traj.tum", "# t x y z qx qy qz qw\n\n1.0 1 2 3 0 0 0 2\n1.5  4 5 6  0 0 1 1\n")
    s = read_tum(path, "traj")
    assert s.columns == POSE_COLUMNS and s.is_pose
    np.testing.assert_array_equal(s.t, [1.0, 1.5])
    np.testing.assert_allclose(s.values, [[1, 2, 3, 0, 0, 0, 1], [4, 5, 6, 0, 0, SQRT_HALF, SQRT_HALF]],
                               atol=1e-15)
    yaw = s.poses()[1].rotation().yaw()
    assert yaw == pytest.approx(np.pi / 2, abs=1e-12)


@pytest.mark.parametrize("body, line, message", [
    ("0 1 2 3 0 0 0 1\n1 1 2 3 0 0 1\n", 3, "7 fields; expected 8 (t x y z qx qy qz qw)"),
    ("0 1 2 3 0 0 0 1\n# c\n1 1 two 3 0 0 0 1\n", 4,
     "field 3 (y) is 'two'; expected a number (fields: t x y z qx qy qz qw)"),
    ("0 1 2 3 0 0 0 1\n1 1 2 3 0 0 0 0\n2 1 2 3 0 0 0 0\n", 3,
     "2 row(s) have a zero quaternion (first at line 3); expected a unit quaternion qx qy qz qw"),
    ("0 1 2 3 0 0 0 1\n\n1 nan 2 3 0 0 0 1\n", 4,
     "1 row(s) contain NaN or infinite values (first at line 4); expected finite numbers"),
    ("1 1 2 3 0 0 0 1\n# c\n\n0 1 2 3 0 0 0 1\n1 1 2 3 0 0 0 1\n", 5,
     "1 row(s) have timestamps that go back in time (first at line 5); expected non-decreasing t in seconds"),
])
def test_tum_errors_name_the_physical_line(tmp_path, body, line, message):
    path = write(tmp_path, "bad.tum", "# t x y z qx qy qz qw\n" + body)
    with pytest.raises(DataError) as err:
        read_tum(path, "bad")
    assert str(err.value) == f"{path}:{line}: {message}"


def test_tum_without_poses_says_no_poses(tmp_path):
    path = write(tmp_path, "empty.tum", "# nothing here\n\n")
    with pytest.raises(DataError) as err:
        read_tum(path, "e")
    assert str(err.value) == f"{path}: no poses; expected lines 't x y z qx qy qz qw'"


def test_tum_round_trip_gives_back_times_and_poses_to_1e_9(tmp_path):
    arr = np.array([[0.5, -1.0, 2.0, 0, 0, 0, 1], [1.5, -2.0, 2.5, 0, 0, SQRT_HALF, SQRT_HALF]])
    s = Stream("p", np.array([10.0, 10.5]), POSE_COLUMNS, arr)
    write_tum(tmp_path / "p.tum", s)
    back = read_tum(tmp_path / "p.tum", "p")
    np.testing.assert_allclose(back.t, [10.0, 10.5], atol=1e-9)
    np.testing.assert_allclose(back.values, arr, atol=1e-9)


# ---------------------------------------------------------------- plain files, parsed in C


def random_rows(n: int, width: int) -> list[list[str]]:
    """Rows of numbers as a file holds them: increasing t, then values of many magnitudes and digits."""
    rng = np.random.default_rng(11)
    a = rng.normal(size=(n, width)) * 10.0 ** rng.integers(-12, 6, size=(n, width))
    a[:, 0] = np.cumsum(rng.uniform(0.001, 0.1, n))
    return [[repr(float(x)) if j % 2 else f"{x:.9f}" for j, x in enumerate(r)] for r in a]


def test_plain_tum_and_csv_give_the_numbers_of_the_line_by_line_readers(tmp_path):
    rows = random_rows(300, 8)
    for row in rows:
        row[4:] = ["0", "0", "0", "1"]
    lines = [" ".join(r) for r in rows]
    plain = write(tmp_path, "plain.tum", "# t x y z qx qy qz qw\n\n" + "\n".join(lines) + "\n")
    crlf = write(tmp_path, "crlf.tum", "# t x y z qx qy qz qw\r\n" + "\r\n".join(lines))
    mixed = write(tmp_path, "mixed.tum", "\n".join(lines[:150] + ["# a comment between rows"] + lines[150:]))
    assert plain_table(plain.read_bytes(), 8) is not None and plain_table(crlf.read_bytes(), 8) is not None
    assert plain_table(mixed.read_bytes(), 8) is None  # read line by line
    expected = np.array([[float(x) for x in r] for r in rows])
    for path in (plain, crlf, mixed):
        s = read_tum(path, "p")
        assert s.t.tobytes() == expected[:, 0].tobytes() and s.values.tobytes() == expected[:, 1:].tobytes()

    rows = random_rows(300, 4)
    lines = [",".join(r) for r in rows]
    plain = write(tmp_path, "plain.csv", "# encoders\nt, a ,b,c\n" + "\n".join(lines) + "\n")
    quoted = write(tmp_path, "quoted.csv", "t,a,b,c\n" + "\n".join(lines[:-1] + ['"' + lines[-1] + '"']) + "\n")
    assert plain_csv(plain.read_bytes()) is not None and plain_csv(quoted.read_bytes()) is None
    expected = np.array([[float(x) for x in r] for r in rows])
    s = read_csv_stream(plain, "e")
    assert s.columns == ("a", "b", "c")
    assert s.t.tobytes() == expected[:, 0].tobytes() and s.values.tobytes() == expected[:, 1:].tobytes()
    with pytest.raises(DataError, match=r"quoted\.csv:301: row has 1 columns; header has 4"):
        read_csv_stream(quoted, "e")


def test_errors_and_notes_of_plain_files_name_the_physical_line(tmp_path):
    tum = write(tmp_path, "a.tum", "# poses\n#\n0 1 2 3 0 0 0 1\n1 1 2 3 0 0 0 2\n2 1 2 inf 0 0 0 1\n")
    with pytest.raises(DataError) as err:
        read_tum(tum, "a")
    assert str(err.value) == (f"{tum}:5: 1 row(s) contain NaN or infinite values (first at line 5); "
                              "expected finite numbers")
    tum = write(tmp_path, "b.tum", "# poses\n#\n0 1 2 3 0 0 0 1\n1 1 2 3 0 0 0 2\n")
    assert read_tum(tum, "b").notes == [f"{tum}: 1 of 2 quaternions had a norm off 1 by more than 0.001 (largest 1, "
                                        "first at line 4); renormalized"]
    csv = write(tmp_path, "c.csv", "\n# wheels\nt,left\n0,1\n1,2\n0.5,3\n")
    with pytest.raises(DataError) as err:
        read_csv_stream(csv, "c")
    assert str(err.value) == (f"{csv}:6: 1 row(s) have timestamps that go back in time (first at line 6); "
                              "expected non-decreasing t in seconds")


# ---------------------------------------------------------------- sample checks


def test_check_samples_uses_given_line_numbers_else_first_line():
    t = np.array([0.0, 1.0, 0.5])
    v = np.zeros((3, 1))
    with pytest.raises(DataError, match=r"^f:12: 1 row\(s\) have timestamps that go back in time \(first at line 12\)"):
        check_samples(t, v, "f", lines=np.array([3, 7, 12]))
    with pytest.raises(DataError, match=r"^f:4: 1 row\(s\)"):
        check_samples(t, v, "f", first_line=2)
    with pytest.raises(DataError, match=r"^s: no samples"):
        check_samples(np.array([]), np.zeros((0, 1)), "s")
    check_samples(np.array([0.0, 0.5]), np.array([[1.0], [2.0]]), "ok")  # no error


def test_stream_constructor_rejects_a_nan_sample_naming_its_row():
    with pytest.raises(DataError, match=r"^gps:2: 1 row\(s\) contain NaN"):
        Stream("gps", [0.0, 1.0], ("x",), [[0.0], [np.nan]])


# ---------------------------------------------------------------- association


def test_nearest_pairs_each_state_with_its_closest_sample_within_tolerance():
    states = np.array([0.0, 1.0, 2.0, 3.0])
    samples = np.array([0.04, 0.98, 1.03, 2.5, 3.2])
    a = nearest(states, samples, tolerance=0.1)
    # 0.04 -> state 0; 0.98 and 1.03 both -> state 1 (0.98 is closer, 1.03 is dropped);
    # 2.5 is 0.5 from any state; 3.2 is 0.2 from state 3: both beyond the tolerance
    np.testing.assert_array_equal(a.state, [0, 1])
    np.testing.assert_array_equal(a.row, [0, 1])
    assert a.unmatched == 3
    wide = nearest(states, samples, tolerance=0.5)
    np.testing.assert_array_equal(wide.state, [0, 1, 2, 3])
    np.testing.assert_array_equal(wide.row, [0, 1, 3, 4])  # 2.5 is a tie between 2 and 3: the earlier state
    assert wide.unmatched == 1


def test_nearest_with_one_state_or_samples_outside_the_span_matches_within_tolerance():
    a = nearest(np.array([5.0]), np.array([4.8, 5.05, 7.0]), tolerance=0.1)
    np.testing.assert_array_equal(a.state, [0])
    np.testing.assert_array_equal(a.row, [1])
    assert a.unmatched == 2
    b = nearest(np.array([1.0, 2.0]), np.array([-3.0, 0.95, 9.0]), tolerance=0.1)
    np.testing.assert_array_equal(b.state, [0])
    np.testing.assert_array_equal(b.row, [1])
    assert b.unmatched == 2


def test_interpolate_poses_linear_position_and_slerp_rotation():
    t = np.array([0.0, 2.0, 4.0])
    yaw90 = [0, 0, SQRT_HALF, SQRT_HALF]
    poses = np.array([[0, 0, 0, 0, 0, 0, 1], [2, 4, -2, *yaw90], [2, 4, 0, *yaw90]])
    inside, out = interpolate_poses(t, poses, np.array([-1.0, 0.0, 1.0, 3.0, 4.0, 5.0]))
    np.testing.assert_array_equal(inside, [False, True, True, True, True, False])
    assert out.shape == (4, 7)
    np.testing.assert_allclose(out[:, :3], [[0, 0, 0], [1, 2, -1], [2, 4, -1], [2, 4, 0]], atol=1e-12)
    # halfway between yaw 0 and yaw 90 deg: yaw 45 deg, quaternion (0, 0, sin 22.5, cos 22.5)
    half = np.array([0, 0, np.sin(np.pi / 8), np.cos(np.pi / 8)])
    np.testing.assert_allclose(np.abs(out[1, 3:]), half, atol=1e-12)
    np.testing.assert_allclose(np.abs(out[0, 3:]), [0, 0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(np.abs(out[2, 3:]), yaw90, atol=1e-12)


def test_interpolate_poses_drops_queries_across_a_gap():
    t = np.array([0.0, 1.0, 5.0])
    poses = np.array([[0, 0, 0, 0, 0, 0, 1], [1, 0, 0, 0, 0, 0, 1], [5, 0, 0, 0, 0, 0, 1]])
    inside, out = interpolate_poses(t, poses, np.array([0.5, 1.0, 3.0, 4.5, 5.0]), max_gap=2.0)
    # 3.0 and 4.5 lie inside the 4 s gap; 1.0 and 5.0 fall on samples, so they need no interpolation
    np.testing.assert_array_equal(inside, [True, True, False, False, True])
    np.testing.assert_allclose(out[:, 0], [0.5, 1.0, 5.0], atol=1e-12)
    inside, out = interpolate_poses(t, poses, np.array([0.5, 1.0, 3.0, 4.5]))
    np.testing.assert_array_equal(inside, [True, True, True, True])
    np.testing.assert_allclose(out[:, 0], [0.5, 1.0, 3.0, 4.5], atol=1e-12)


def test_interpolate_poses_with_a_single_sample_answers_only_at_its_time():
    poses = np.array([[1, 2, 3, 0, 0, 0, 1]], dtype=float)
    inside, out = interpolate_poses(np.array([2.0]), poses, np.array([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(inside, [False, True, False])
    np.testing.assert_array_equal(out, poses)


def test_segment_ids_split_at_gaps():
    t = np.array([0.0, 1.0, 5.0, 6.0, 6.5])
    np.testing.assert_array_equal(segment_ids(t, np.array([0.5, 3.0, 5.5, 6.2, 9.0]), max_gap=2.0), [0, 0, 1, 1, 1])
    np.testing.assert_array_equal(segment_ids(t, np.array([0.5, 3.0]), max_gap=None), [0, 0])
