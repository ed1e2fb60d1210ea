"""The figure cache (planner.report.figure_cache): a figure drawn again from the same data is read
back, byte for byte what its rendering gives; other data, a damaged entry or ``cache=False``
render again; the folder is kept under its size limit."""

from __future__ import annotations

import os

import numpy as np
import pytest

from planner.report import figure_cache, rendering
from planner.report.rendering import FigureItem, job


def line_figure(y: np.ndarray, title: str = ""):
    """A small figure job for these tests (module level: jobs are pickled)."""
    from planner.report.figure_base import new_figure as _figure

    fig = _figure(3.0, 2.0)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(np.asarray(y))
    ax.set_title(title)
    return fig


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.delenv("COMPPLAN_FIGURE_CACHE", raising=False)
    monkeypatch.setenv("COMPPLAN_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache" / figure_cache.FIGURE_CACHE_FOLDER


@pytest.fixture
def counted(monkeypatch):
    """Counts the figures actually rendered."""
    calls: list[str] = []
    fresh = rendering.render_fresh

    def counting(items, *args, **kwargs):
        calls.extend(it.name for it in items if it.job is not None)
        return fresh(items, *args, **kwargs)

    monkeypatch.setattr(rendering, "render_fresh", counting)
    return calls


def _items(y=(0.0, 1.0, 0.5), title="a") -> list[FigureItem]:
    return [
        FigureItem("f1", "t", "c", job=job(line_figure, np.asarray(y), title=title)),
        FigureItem("f2", "t", "c", absent="not in this run"),
    ]


def test_a_figure_drawn_again_is_read_back_byte_for_byte(cache, counted):
    first, second = _items(), _items()
    rendering.render_items(first, workers=1)
    assert counted == ["f1"] and len(list(cache.iterdir())) == 1
    ticks: list[tuple] = []
    rendering.render_items(second, progress=lambda *a: ticks.append(a), workers=1)
    assert counted == ["f1"]  # not rendered again
    assert (second[0].png, second[0].pdf) == (first[0].png, first[0].pdf) and first[0].pdf
    assert second[1].png is None and ticks == [("figures", 1, 1)]
    assert (second[0].png, second[0].pdf) == rendering.render_job(_items()[0].job)


@pytest.mark.parametrize("change", [{"y": (0.0, 1.0, 0.6)}, {"title": "b"}])
def test_other_data_is_rendered(cache, counted, change):
    rendering.render_items(_items(), workers=1)
    rendering.render_items(_items(**change), workers=1)
    assert counted == ["f1", "f1"] and len(list(cache.iterdir())) == 2


def test_png_only_and_with_pdf_are_different_entries(cache, counted):
    rendering.render_items(_items(), workers=1, pdf=False)
    items = _items()
    rendering.render_items(items, workers=1)
    assert counted == ["f1", "f1"] and items[0].pdf


def test_a_damaged_entry_is_rendered_again_and_replaced(cache, counted):
    good = _items()
    rendering.render_items(good, workers=1)
    (entry,) = cache.iterdir()
    data = entry.read_bytes()
    entry.write_bytes(data[:-10] + bytes(10))  # same length, other bytes
    again = _items()
    rendering.render_items(again, workers=1)
    assert counted == ["f1", "f1"] and again[0].png == good[0].png and entry.read_bytes() == data
    entry.write_bytes(data[:100])  # truncated
    rendering.render_items(_items(), workers=1)
    assert counted == ["f1"] * 3


def test_without_cache_nothing_is_read_or_kept(cache, counted):
    rendering.render_items(_items(), workers=1, cache=False)
    rendering.render_items(_items(), workers=1, cache=False)
    assert counted == ["f1", "f1"] and not cache.exists()


def test_the_cache_is_kept_under_its_size(cache, counted, monkeypatch):
    rendering.render_items(_items(title="a"), workers=1)
    (first,) = cache.iterdir()
    old = first.stat().st_mtime - 60.0
    os.utime(first, (old, old))  # used a minute ago
    monkeypatch.setattr(figure_cache, "FIGURE_CACHE_MAX_BYTES", first.stat().st_size * 2 + 1)
    for title in ("b", "c"):
        rendering.render_items(_items(title=title), workers=1)
    left = list(cache.iterdir())
    assert len(left) == 2 and first not in left  # the least recently used went first


def test_an_unusable_cache_folder_only_costs_the_rendering(tmp_path, monkeypatch, counted):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.delenv("COMPPLAN_FIGURE_CACHE", raising=False)
    monkeypatch.setenv("COMPPLAN_CACHE", str(blocker))
    items = _items()
    rendering.render_items(items, workers=1)
    assert items[0].png and counted == ["f1"]


def test_the_figure_cache_folder_can_be_named(tmp_path, monkeypatch, counted):
    """``$COMPPLAN_FIGURE_CACHE`` names the folder (the tests' own); ``$COMPPLAN_CACHE`` is then untouched."""
    monkeypatch.setenv("COMPPLAN_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("COMPPLAN_FIGURE_CACHE", str(tmp_path / "figs"))
    rendering.render_items(_items(), workers=1)
    rendering.render_items(_items(), workers=1)
    assert counted == ["f1"]  # the second rendering read the first back
    assert any((tmp_path / "figs").iterdir())
    assert not (tmp_path / "cache" / figure_cache.FIGURE_CACHE_FOLDER).exists()
