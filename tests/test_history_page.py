"""The results page's history section (longtime.reporting.history_page): what moved, as a
reader asks it of a store of many runs, without a panel per repeated cell."""
import re

from longtime.reporting import history_page
from longtime.reporting.history import TIME_FIELD


def _cell(problem, i, ratio=None, same_commit=True):
    runs = [{"run_id": r, "commit": "a" * 40 if same_commit or r == 1 else "b" * 40, "status": "ok",
             TIME_FIELD: 1.0 if r == 1 or ratio is None else ratio, "l2_error": 1e-6} for r in (1, 2)]
    steps = [] if ratio is None else [{"field": TIME_FIELD, "run_id": 2, "commit": runs[1]["commit"], "before": 1.0,
                                       "after": ratio, "ratio": ratio, "kind": "slower" if ratio > 1 else "faster"}]
    return {"cell": {"problem": problem, "integrator": "rk4", "dt": 0.0253036559 * (i + 1), "t_final": 100.0},
            "runs": runs, "steps": steps}


def test_the_section_counts_what_held_lists_what_moved_and_draws_only_the_largest(monkeypatch):
    cells = [_cell("kepler", i) for i in range(300)]  # held their level
    cells += [_cell("kepler", 300 + i, ratio=1.5 + 0.1 * i) for i in range(20)]
    cells += [_cell("toda", i, ratio=0.4, same_commit=False) for i in range(2)]
    monkeypatch.setattr(history_page, "repeated", lambda store, rows: cells)
    html = history_page.page_section(None, [], {})
    assert "322 cells of this page are in more than one of 2 stored runs; 300 held" in html
    assert "22 stepped" in html
    # one figure, FIGURE_CELLS panels: the largest steps (kepler's x3.4 first)
    assert html.count("<svg") == 1
    assert len(re.findall(r'<g id="[0-9a-f]+-axes_\d+"', html)) == history_page.FIGURE_CELLS
    # a table per problem that moved, the largest steps first, capped and counted
    kepler = html[html.index('id="history-kepler"'):html.index('id="history-toda"')]
    assert f"20 cells, 20 steps marked, the {history_page.TABLE_ROWS} largest listed" in kepler
    assert kepler.count("<tr>") == history_page.TABLE_ROWS + 1
    assert kepler.index("x3.4") < kepler.index("x2.5")
    assert "dt=8.097 " in kepler and "(same commit)" in kepler  # 4 digits; between runs of one commit
    toda = html[html.index('id="history-toda"'):]
    assert "2 cells, 2 steps marked (" in toda and "x0.4" in toda and "faster" in toda
    assert "(same commit)" not in toda and "run 1 (aaaaaaa) -&gt; 2 (bbbbbbb)" in toda


def test_a_store_whose_cells_held_their_level_draws_nothing(monkeypatch):
    monkeypatch.setattr(history_page, "repeated", lambda store, rows: [_cell("kepler", i) for i in range(5)])
    html = history_page.page_section(None, [], {})
    assert "5 cells" in html and "5 held" in html and "0 stepped" in html
    assert "<svg" not in html and "<table" not in html
    monkeypatch.setattr(history_page, "repeated", lambda store, rows: [])
    assert history_page.page_section(None, [], {}) is None
