"""Bad command lines and bad files get one line of error from every command, never a library traceback."""

import pytest

from lagrangian.cli import main

BAD = [
    ["simulate"], ["simulate", "{d}/missing.cir"], ["simulate", "{d}/bad.cir"], ["simulate", "{d}/bad.json"],
    ["simulate", "{d}/notmodel.py"], ["simulate", "{d}/ok.cir", "--t-end", "-1"],
    ["simulate", "{d}/ok.cir", "--t-end", "nan"], ["simulate", "{d}/ok.cir", "--points", "1e12"],
    ["simulate", "{d}/ok.cir", "--param", "x"], ["simulate", "{d}/ok.cir", "--param", "R_R1=abc"],
    ["simulate", "{d}/ok.cir", "--initial", "zz=1"], ["simulate", "{d}/ok.cir", "--method", "nope"],
    ["simulate", "{d}/ok.cir", "--out", "/nonexistent/dir/x.csv"], ["simulate", "{d}/ok.cir", "--out", "{d}/x.xyz"],
    ["simulate", "{d}/ok.cir", "--out", "{d}"], ["simulate", "{d}/ok.cir", "--velocity", "a=1"],
    ["simulate", "{d}/ok.cir", "--initial", "=1"], ["simulate", "/dev/zero"],
    ["equations", "{d}/bad.cir"], ["equations", "{d}/missing.py:build"], ["equations", "{d}/notmodel.py:nothing"],
    ["equations", "{d}/notmodel.py:x"], ["equations", "/dev/null"],
    ["convert", "{d}/ok.cir"], ["convert", "{d}/ok.cir", "--out", "/nonexistent/x.json"],
    ["convert", "{d}/bad.json", "--out", "{d}/y.json"], ["convert", "/dev/null", "--out", "{d}/z.json"],
    ["ac", "{d}/ok.cir"], ["ac", "{d}/bad.cir"], ["ac", "{d}/ok.cir", "--points", "0"], ["ac", "/dev/zero"],
    ["ac", "{d}/ok.cir", "--input", "nope"],
    ["scene", "{d}/bad.cir"], ["scene", "--points", "1e12", "{d}/ok.cir"],
    ["sweep", "{d}/ok.cir"], ["sweep", "{d}/notmodel.py:x", "--param", "k=1:2:3"],
    ["sweep", "{d}/ok.cir", "--param", "R_R1=1:2:nan"],
    ["sweep", "{d}/ok.cir", "--address", "file:///x", "--param", "R_R1=1:2:3"],
    ["bench", "nope"], ["bench", "--repeat", "0"], ["kinds", "extra"], ["cache", "--clear", "--nope"], ["nope"], [],
]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    (d / "ok.cir").write_text("V1 a 0 DC 1\nR1 a 0 1k\n.end\n")
    (d / "bad.cir").write_bytes(b"\xff\xfe not text")
    (d / "notmodel.py").write_text("x = 1\n")
    (d / "bad.json").write_text('{"a":')
    return d


@pytest.mark.parametrize("argv", BAD, ids=[" ".join(a) or "(nothing)" for a in BAD])
def test_a_bad_call_is_one_line_of_error_and_a_failing_status(argv, files, capsys):
    try:
        status = main([a.format(d=files) for a in argv])
    except SystemExit as exc:  # argparse's usage errors
        status = exc.code
    err = capsys.readouterr().err
    assert status in (1, 2), (status, err)
    assert "Traceback" not in err and "error:" in err, err
