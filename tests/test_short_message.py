"""A message cut for a report line ends at a clause or a word (s37: a trim's report
ended "a fin or sliver too thin to be stored (it is near t", cut at 300 characters)."""

from __future__ import annotations

from lattice_cad.lattice import _short

PINCHED = (
    "the lattice: 0 triangle(s) collapse and 2 vertex(es) are pinched when coordinates are "
    "rounded to single precision (as STL and 3MF store them), e.g. near (33.8494, -38, "
    "8.14382); two of its surfaces lie closer there than a float32 step (3.8e-06 mm), a fin "
    "or sliver too thin to be stored (it is near the origin already: moving it would not "
    "help); use thicker struts, or other cell sizes or skin thicknesses\nsecond line"
)


def test_cut_at_the_end_of_a_clause():
    out = _short(PINCHED, 300)
    assert out == PINCHED.split("; ")[0] + "..."
    assert len(out) <= 300


def test_cut_at_a_word_when_no_clause_ends_early_enough():
    out = _short("one two three four five six seven", 16)
    assert out == "one two three..." and len(out) <= 16


def test_short_messages_are_kept_whole():
    assert _short("all of it\nnot this", 100) == "all of it"
    assert _short("", 10) == ""
