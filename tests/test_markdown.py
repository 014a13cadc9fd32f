"""markdown_table against tables written out by hand."""

import pytest

from drake_continuum.markdown import markdown_row, markdown_table


def test_a_table_is_its_header_alignment_and_rows():
    lines = markdown_table(["a", "b"], [[1, ""], ["x", 2.5]], align=["---", "---:"])
    assert lines == ["| a | b |", "|---|---:|", "| 1 |  |", "| x | 2.5 |"]
    assert markdown_table(["only"]) == ["| only |", "|---|"]
    assert markdown_row(["flip", "1 %"]) == "| flip | 1 % |"


def test_alignments_must_match_the_columns():
    with pytest.raises(ValueError, match="1 alignments for 2 columns"):
        markdown_table(["a", "b"], align=["---"])
