"""docs/schemes.md names every built-in scheme registered through the ``longtime.integrators``
entry-point group (pyproject.toml, read from the installed metadata), in backquotes; a
plugin's entry points (an installed example plugin's) are its own docs' business."""
import importlib.metadata
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "schemes.md"


def test_every_entry_point_is_named():
    text = DOC.read_text()
    names = sorted(ep.name for ep in importlib.metadata.entry_points(group="longtime.integrators")
                   if ep.value.startswith("longtime.integrators."))
    assert len(names) >= 40  # the built-ins' entry points are installed
    missing = [name for name in names if f"`{name}`" not in text]
    assert missing == [], f"docs/schemes.md does not name {missing}"
