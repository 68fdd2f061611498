"""emasim.page_blocks: one rule for every generated block of the README and the docs."""

import pytest

from emasim.page_blocks import block_of, markers, with_block

PAGE = "intro\n<!-- table:begin -->\n| a |\n| 1 |\n<!-- table:end -->\nafter\n"


def test_the_body_is_between_the_marker_lines_less_the_last_newline():
    assert markers("table") == ("<!-- table:begin -->", "<!-- table:end -->")
    assert block_of(PAGE, "table") == "| a |\n| 1 |"
    assert with_block(PAGE, "table", "| b |") == PAGE.replace("| a |\n| 1 |", "| b |")


@pytest.mark.parametrize("body", ["", "x", "\nx\n", "x\n\n", "\n"])
def test_a_written_body_reads_back_as_written(body):
    """An empty body, and bodies that frame themselves with empty lines, round-trip; the
    text around the block is kept."""
    text = with_block(PAGE, "table", body)
    assert block_of(text, "table") == body
    assert text.startswith("intro\n<!-- table:begin -->\n") and text.endswith("end -->\nafter\n")
    assert with_block(text, "table", "| a |\n| 1 |") == PAGE


def test_a_page_without_the_block_is_an_error():
    with pytest.raises(ValueError):
        block_of(PAGE, "other")
    with pytest.raises(ValueError):
        with_block("<!-- table:begin --> no newline <!-- table:end -->", "table", "x")
