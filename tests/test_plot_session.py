"""The API's figures in a user's session: ``import longtime`` is enough for longtime.plot and
longtime.testing; a figure of the API leaves rcParams as they were, its tick labels and the
user's own figure's render (no raw $\\mathdefault{...}$), the user's text stays as typed, a
scheme that is not built in has a colour of its own, and the legend is outside the axes."""
import subprocess
import sys
import textwrap

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from longtime.integrators import Splitting, compose  # noqa: E402

G = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))


class My_FR(Splitting):  # noqa: N801  (user text is drawn as typed)
    name = "my-fr"
    order = 4
    kicks, drifts = compose([G, 1.0 - 2.0 * G, G])


def test_import_longtime_gives_plot_and_testing_compiling_nothing():
    probe = textwrap.dedent('''
        import sys, longtime
        from numba.core.registry import CPUDispatcher
        assert callable(longtime.plot.work_precision) and callable(longtime.plot.drift)
        assert callable(longtime.testing.assert_order)
        compiled = [v for n, m in list(sys.modules.items()) if n.startswith("longtime")
                    for v in vars(m).values() if isinstance(v, CPUDispatcher) and v.signatures]
        print(len(compiled))
    ''')
    res = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "0"


def _renders(label) -> bool:
    """A tick label renders: plain text, or mathtext that is parsed."""
    return "$" not in label.get_text() or label.get_parse_math()


def test_api_figure_then_own_figure_render_and_leave_rcparams_unchanged():
    """In a session with matplotlib's defaults (the results page's figures, drawn by other tests
    of this process, turn mathtext off process-wide)."""
    with matplotlib.rc_context({"text.parse_math": True}):
        _api_figure_then_own_figure()


def _api_figure_then_own_figure():
    import longtime

    before = dict(matplotlib.rcParams)
    rows = longtime.sweep("harmonic", ["verlet", "rk4", My_FR], dt=[0.1, 0.05], t_final=5, executor="serial")
    ax = longtime.plot.work_precision(rows)
    ax.figure.canvas.draw()
    assert dict(matplotlib.rcParams) == before
    labels = ax.get_xticklabels() + ax.get_yticklabels()
    assert labels and all(_renders(t) for t in labels) and any(t.get_text() for t in labels)
    assert not any("mathdefault" in t.get_text() for t in labels)
    # the user's own figure afterwards: matplotlib's defaults, mathtext parsed
    fig, own = plt.subplots()
    own.loglog([1e-3, 1e-1], [1e-6, 1e-2])
    own.set_title(r"$\alpha$ drift")
    fig.canvas.draw()
    assert matplotlib.rcParams["text.parse_math"] is True
    assert own.title.get_parse_math()
    own_labels = own.get_xticklabels() + own.get_yticklabels()
    assert any("mathdefault" in t.get_text() for t in own_labels) and all(_renders(t) for t in own_labels)
    # the user's scheme name is drawn as typed
    legend = ax.get_legend()
    texts = [t for t in legend.get_texts() if "my-fr" in t.get_text()]
    assert texts and not texts[0].get_parse_math()
    # a colour of its own: not the splitting family's colour that verlet has
    colours = {line.get_label().split()[0]: line.get_color() for line in ax.get_lines()}
    assert colours["my-fr"] != colours["verlet"] and colours["my-fr"] != colours["rk4"]
    plt.close("all")


def test_drift_legend_is_outside_the_axes():
    import longtime

    rows = longtime.sweep("harmonic", ["verlet", "rk4", "yoshida6", "midpoint", My_FR],
                          dt=[0.2, 0.1, 0.05, 0.025, 0.0125, 0.00625, 0.003125], t_final=5, executor="serial")
    ax = longtime.plot.drift(rows, invariant="H")
    fig = ax.figure
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    box, axbox = ax.get_legend().get_window_extent(renderer), ax.get_window_extent(renderer)
    assert len(ax.get_legend().get_texts()) == 35
    assert box.x0 >= axbox.x1  # right of the axes, not over them
    assert box.x1 <= fig.bbox.x1 + 1  # and inside the figure (constrained layout)
    plt.close("all")
