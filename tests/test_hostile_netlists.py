"""Netlists of bounded size and cost: what a hostile or careless deck can ask of the reader is refused, with a
:class:`~lagrangian.ModelError` naming the file or line, the size and the bound (``lagrangian.limits``), before the
work — and what is within the bounds costs memory in proportion to the deck.

- a file is read to at most ``limits.file_bytes`` (``/dev/zero`` is refused, not read forever), and text given as a
  string is held to the same bound;
- a file that is not UTF-8 text is refused by the reader itself (every caller: ``read_netlist_file``, the
  ``ac`` and ``scene`` commands), naming the file and the line;
- a deck with more than ``limits.netlist_elements`` elements is refused while it is parsed, at the first element
  beyond the bound;
- capacitors in parallel: the initial state's weights are not a dense n × n matrix;
- two ``K`` lines coupling the same pair of inductors are refused while parsing (a look-up by the pair), and
  thousands of distinct ones are read.

Costs are measured by ``benchmarks/hostile_netlists.py``, not here: these tests check outcomes and memory, never
wall time.
"""

from __future__ import annotations

import tracemalloc

import pytest

import lagrangian as lg
from lagrangian.circuits import initial_state
from lagrangian.circuits.initial_state import _initial_state
from lagrangian.circuits.netlist import read_netlist, read_netlist_file
from lagrangian.cli import main

RC = "rc\nV1 a 0 DC 1\nR1 a b 1k\nC1 b 0 1u\n.tran 1u 1m\n.end\n"


def parallel(n: int, letter: str = "R") -> str:
    """A deck of ``n`` elements: a source and ``n − 1`` elements in parallel across it."""
    return "\n".join(["parallel", "V1 a 0 DC 1", *(f"{letter}{i} a 0 1k" for i in range(n - 1)), ".end"]) + "\n"


# --- 1. bytes ------------------------------------------------------------------------------------------------


def test_an_endless_file_is_refused_past_the_byte_bound():
    with pytest.raises(lg.ModelError, match=r"netlist file '/dev/zero'.*lagrangian\.limits\.file_bytes = 67108864"):
        read_netlist_file("/dev/zero")


def test_a_file_or_text_beyond_the_byte_bound_is_refused_and_one_at_it_is_read(tmp_path):
    size = len(RC.encode())
    path = tmp_path / "rc.cir"
    path.write_text(RC)
    with lg.limits(file_bytes=size):
        assert read_netlist_file(path).title == "rc"
        assert read_netlist(RC).title == "rc"
    with lg.limits(file_bytes=size - 1):
        with pytest.raises(lg.ModelError, match=rf"netlist file '.*rc\.cir' asks for {size} bytes, beyond "
                                                rf"lagrangian\.limits\.file_bytes = {size - 1}; raise it"):
            read_netlist_file(path)
        with pytest.raises(lg.ModelError, match=rf"netlist text asks for {size} bytes, beyond "
                                                rf"lagrangian\.limits\.file_bytes = {size - 1}"):
            read_netlist(RC)
    # text is counted in UTF-8 bytes, not characters: a title of 'Ω' is two of them
    omega = RC.replace("rc\n", "Ω\n", 1)
    with lg.limits(file_bytes=len(omega) + 1):
        read_netlist(omega)
    with lg.limits(file_bytes=len(omega)):
        with pytest.raises(lg.ModelError, match=rf"asks for {len(omega) + 1} bytes"):
            read_netlist(omega)


# --- 2. not text -----------------------------------------------------------------------------------------------


@pytest.fixture
def binary(tmp_path):
    path = tmp_path / "latin1.cir"
    path.write_bytes("résistances\nV1 a 0 DC 1\nR1 a 0 1k ; 1 kΩ\n.end\n".encode("latin-1", errors="replace"))
    return path


def test_a_file_that_is_not_utf8_is_refused_naming_the_file_and_the_line(binary, tmp_path):
    with pytest.raises(lg.ModelError, match=r"netlist file '.*latin1\.cir' is not a text file: byte 0xe9 at offset 1 "
                                            r"\(line 1\) is not UTF-8.*saved as UTF-8"):
        read_netlist_file(binary)
    nul = tmp_path / "nul.cir"
    nul.write_bytes(b"title\nV1 a 0 DC 1\nR1 a 0 1k\x00\x00\n.end\n")
    with pytest.raises(lg.ModelError, match=r"'.*nul\.cir' is not a text file: it holds a NUL byte \(line 3\)"):
        read_netlist_file(nul)
    bom = tmp_path / "bom.cir"
    bom.write_bytes(b"\xef\xbb\xbf" + RC.encode())  # a byte-order mark is not part of the title
    assert read_netlist_file(bom).title == "rc"


@pytest.mark.parametrize("command", [["ac"], ["scene", "-o", "v(a)"]])
def test_the_commands_say_a_file_is_not_text(binary, command, capsys):
    assert main([command[0], str(binary), *command[1:]]) == 1
    err = capsys.readouterr().err
    assert "is not a text file" in err and str(binary) in err and "Traceback" not in err
    assert err.count("\n") == 1  # one line


# --- 3. elements ------------------------------------------------------------------------------------------------


def test_a_deck_beyond_the_element_bound_is_refused_while_parsing_and_one_at_it_is_read():
    with lg.limits(netlist_elements=100):
        net = read_netlist(parallel(100))
        assert len(net.model.components) == 100
        # refused at the 101st element's line (line 102, after the title and 100 elements), before the line after it
        # (a MOSFET, refused if it were read) and before any model is built
        with pytest.raises(lg.ModelError, match=r"netlist line 102 \(R99\): .* asks for 101 elements, beyond "
                                                r"lagrangian\.limits\.netlist_elements = 100; raise it"):
            read_netlist(parallel(101).replace(".end", "M1 a b 0 0 nmos\n.end"))
    # the default bound holds 2,000 of them; dot commands and comments are not elements
    text = parallel(2_000).replace(".end", "* a comment\n.options reltol=1e-4\n.end")
    with lg.limits(netlist_elements=2_000):
        assert len(read_netlist(text).model.components) == 2_000


def test_continuation_lines_count_once_and_are_joined():
    text = "cont\nV1 a 0\n+ DC\n+ 2\nR1 a 0\n+ 1k\n.end\n"
    with lg.limits(netlist_elements=2):
        net = read_netlist(text)
    assert net.lines == {"V1": 2, "R1": 5}


# --- 4. parallel capacitors ------------------------------------------------------------------------------------


def test_parallel_capacitors_start_right_without_an_n_by_n_matrix(monkeypatch):
    """1,500 capacitors across a source and resistor (node fluxes: they share one node): the DC operating point
    charges every one to 1 V.  Finding the initial state of n capacitors allocated a dense n × n weight matrix
    (18 MB here; 80 GB at 10⁵); beyond ``_DENSE_ENTRIES`` it is sparse, a few bytes per capacitor, and gives the
    dense path's answer."""
    n = 1_500
    text = "\n".join(["parallel capacitors", "V1 in 0 DC 1", "R1 in a 1k", *(f"C{i} a 0 1n" for i in range(n)),
                      ".tran 1u 10u", ".end"])
    net = read_netlist(text, formulation="flux")
    assert net.ic == pytest.approx({f"C{i}": 1.0 for i in range(n)}, rel=1e-12)
    tracemalloc.start()
    try:
        initial, velocity, moved = _initial_state(net.model, net.ic)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert not moved and initial == net.initial
    assert peak < 4 * 2**20, peak  # the dense weights alone were 18 MB
    monkeypatch.setattr(initial_state, "_DENSE_ENTRIES", 10**7)  # the same state, dense
    dense = _initial_state(net.model, net.ic)
    assert dense[0] == pytest.approx(initial, rel=1e-12, abs=1e-300) and dense[1] == pytest.approx(velocity, abs=1e-15)


def test_the_operating_point_names_a_loop_of_sources_and_inductors_and_a_floating_node():
    with pytest.raises(lg.ModelError, match=r"no DC operating point.*singular in L2, V1, L1 \(a loop of voltage "
                                            r"sources and inductors\)"):
        read_netlist("loop\nV1 a 0 DC 1\nL1 a b 1m\nL2 b 0 1m\nR1 a 0 1k\n.tran 1u 1m\n.end\n")
    with pytest.raises(lg.ModelError, match=r"singular in \.ic v\(a\), V1 \(a loop"):
        read_netlist("held\nV1 a 0 DC 1\nR1 a 0 1k\n.ic v(a)=1\n.tran 1u 1m\n.end\n")
    with pytest.raises(lg.ModelError, match=r"singular in m, n \(a node that only capacitors or current sources"):
        read_netlist("floating\nV1 a 0 DC 1\nC1 a m 1u\nR2 m n 1k\nC2 n 0 1u\nR1 a 0 1k\n.tran 1u 1m\n.end\n")


# --- 5. couplings ------------------------------------------------------------------------------------------------


def coupled_pairs(pairs: int, extra: str = "") -> str:
    """``pairs`` transformers, each a driven coil coupled to a loaded one (``2 · pairs`` inductors, ``pairs`` K
    lines), then ``extra``."""
    lines = ["coupled pairs", "V1 in 0 DC 1"]
    for i in range(pairs):
        lines += [f"R{i} in a{i} 1k", f"La{i} a{i} 0 1m", f"Lb{i} b{i} 0 1m", f"Rb{i} b{i} 0 50", f"K{i} La{i} Lb{i} 0.5"]
    return "\n".join([*lines, extra, ".tran 1u 10u", ".end"])


def test_a_duplicate_coupling_at_the_end_of_a_large_deck_is_refused_naming_both():
    # 2,000 inductors, 1,000 K lines, and a last one coupling the first pair again (in the other order, other case)
    text = coupled_pairs(1_000, "Kagain lb0 LA0 0.3")
    line = 2 + 5 * 1_000 + 1
    with pytest.raises(lg.ModelError, match=rf"netlist line {line} \(Kagain\): couplings 'K0' and 'Kagain' both "
                                            rf"couple La0 and Lb0 \(K0 is on line 7\): give one coupling per pair"):
        read_netlist(text)


def test_three_thousand_distinct_couplings_are_read():
    net = read_netlist(coupled_pairs(3_000))
    couplings = [c for c in net.model.components.values() if c.kind == "coupling"]
    assert len(couplings) == 3_000
    # the DC operating point: each driven coil shorts its node through 1 kΩ, the loaded coil carries no DC current
    assert net.ic["La2999"] == pytest.approx(1e-3, rel=1e-12) and net.ic["Lb2999"] == 0.0


def test_a_duplicate_coupling_built_in_python_is_refused_by_the_numeric_assembly():
    m = lg.Model("pairs")
    m.add("voltage_source", "V1", ("in", "0"), E=1)
    m.add("resistor", "R1", ("in", "a"), R=1e3)
    m.add("inductor", "L1", ("a", "0"), L=1e-3)
    m.add("inductor", "L2", ("b", "0"), L=1e-3)
    m.add("resistor", "R2", ("b", "0"), R=50)
    m.add("coupling", "K1", inductor1="L1", inductor2="L2", k=0.5)
    m.add("coupling", "K2", inductor1="L2", inductor2="L1", k=0.2)
    with pytest.raises(lg.ModelError, match=r"couplings 'K1' and 'K2' both couple L1 and L2: give one coupling per"):
        m.simulate(1e-5)
