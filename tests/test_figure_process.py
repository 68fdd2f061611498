"""The figure process (emasim.analysis.figure_process): the same files as drawing in place,
its errors raised in the writer, and no hang when it dies.

Each test forks a real figure process; nothing here is timed.
"""

import dataclasses
import os
import signal
from pathlib import Path

import pytest

from emasim.analysis.figure_process import (
    DrawHere,
    FigureProcess,
    FigureProcessError,
    can_fork,
    figure_writer,
)
from emasim.output import foreign_files
from emasim.scenarios.loader import load_scenario
from emasim.sim.engine import simulate

pytestmark = pytest.mark.skipif(not can_fork(), reason="the figure process needs fork (Linux)")


def broken():
    """A figure whose drawing raises."""
    raise ValueError("no such column: rudder_deg")


def dies():
    """A figure whose drawing ends the figure process."""
    os._exit(3)


@pytest.fixture(scope="module")
def result():
    return simulate(load_scenario("speed-step", settings=["duration_s=0.02"]).setup())


def test_a_saved_run_has_the_same_plot_drawn_here_or_by_the_figure_process(result, tmp_path):
    here = result.save(tmp_path / "here", figures=DrawHere())
    with figure_writer() as figures:
        assert isinstance(figures, FigureProcess)
        there = result.save(tmp_path / "there", figures=figures)
    assert (here / "plot.png").read_bytes() == (there / "plot.png").read_bytes()
    assert foreign_files(there) == []  # the child's PNG is in the build's journal


def test_an_error_in_drawing_is_raised_by_wait(tmp_path):
    with figure_writer() as figures:
        figures.save(broken, tmp_path / "x.png")
        with pytest.raises(ValueError, match="no such column"):
            figures.wait()
    assert not (tmp_path / "x.png").exists()


def test_a_figure_process_that_dies_is_an_error_not_a_hang(tmp_path):
    with figure_writer() as figures:
        figures.save(dies, tmp_path / "x.png")
        with pytest.raises(FigureProcessError, match="exit code 3"):
            figures.wait()


def test_a_failed_figure_fails_the_save_and_leaves_no_folder(result, tmp_path):
    """A run without the columns its plot reads: the same error as drawing it here."""
    bad = dataclasses.replace(result, columns=result.columns[:1], data=result.data[:, :1])
    with pytest.raises(KeyError, match="no column") as here:
        bad.save(tmp_path / "here", figures=DrawHere())
    with figure_writer() as figures, pytest.raises(KeyError) as there:
        bad.save(tmp_path / "there", figures=figures)
    assert str(there.value) == str(here.value)
    assert list(tmp_path.iterdir()) == []


def test_without_plots_there_is_no_figure_process():
    with figure_writer(plot=False) as figures:
        assert figures is None


def priorities():
    """A figure whose drawing reports (raises) the figure process's priorities: its importing
    thread's and its own (the drawing thread's)."""
    from emasim.analysis import figure_process as fp

    raise ValueError(f"{fp._import_niceness} {os.getpriority(os.PRIO_PROCESS, 0)}")


def test_the_figure_process_imports_yielding_every_core_and_draws_at_the_callers_priority(
    tmp_path,
):
    """Its import (while the first process simulates) runs at the lowest CPU priority
    (FIGURE_NICENESS above this process's), so that where every core simulates it takes only
    the cycles they leave; it draws (while the first process waits for it) at this process's
    priority, so that other work on the machine does not hold the figures back."""
    from emasim.analysis import figure_process as fp

    writer = fp.FigureProcess()
    try:
        writer.save(priorities, tmp_path / "x.png")
        with pytest.raises(ValueError) as seen:
            writer.wait()
        own = os.nice(0)
        assert str(seen.value) == f"[{min(19, own + fp.FIGURE_NICENESS)}] {own}"
        assert os.getpriority(os.PRIO_PROCESS, writer._process.pid) == own
    finally:
        writer.close()


def test_save_figure_writes_the_png_of_savefig_and_leaves_the_figure_as_it_was(result, tmp_path):
    """save_figure lays a figure out once, then saves it with its layout engine off (savefig
    would lay it out in a first, undrawn pass): the same bytes as savefig's own way; the
    figure keeps its engine, dpi and canvas."""
    from emasim.analysis.plots import save_figure

    figure = result.plot()
    engine, dpi, canvas = figure.get_layout_engine(), figure.dpi, figure.canvas
    save_figure(figure, tmp_path / "fast.png")
    assert figure.get_layout_engine() is engine and engine is not None
    assert (figure.dpi, figure.canvas) == (dpi, canvas)
    plain = result.plot()
    for ax in plain.axes:  # what save_figure leaves out of the layout, as it does
        for artist in (*ax.get_lines(), *ax.child_axes):
            artist.set_in_layout(False)
    plain.savefig(tmp_path / "plain.png", dpi=110)
    assert (tmp_path / "fast.png").read_bytes() == (tmp_path / "plain.png").read_bytes()


def test_a_figure_process_handed_nothing_is_ended_at_once():
    """A refused input hands no figure: close() ends the process (SIGTERM) rather than wait
    for its import of matplotlib; one that drew its figures ends by itself."""
    idle = FigureProcess()
    idle.close()
    assert idle._process.exitcode == -signal.SIGTERM
    with figure_writer() as figures:
        with pytest.raises(ValueError, match="no such column"):
            figures.save(broken, Path("x.png"))
            figures.wait()
    assert figures._process.exitcode == 0
