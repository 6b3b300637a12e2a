"""mkdocs hook: docs/commands.md's ``<!-- commands -->`` marker becomes a section per
``longtime`` command (and per sub-command, as ``longtime cache info``), each with the help
its argparse parser prints, so the reference lists exactly the commands that
``longtime.commands.cli.build_parser`` registers."""
from __future__ import annotations

import argparse
import os

MARKER = "<!-- commands -->"
WIDTH = "100"  # argparse wraps its help to $COLUMNS


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _summaries(parser: argparse.ArgumentParser) -> dict[str, str]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return {choice.dest: choice.help or "" for choice in action._choices_actions}
    return {}


def command_sections(parser: argparse.ArgumentParser, prefix: str = "longtime", level: int = 2) -> list[str]:
    """One Markdown section per sub-command of ``parser``, nested sub-commands one level deeper."""
    sections = []
    summaries = _summaries(parser)
    for name, sub in _subcommands(parser).items():
        command = f"{prefix} {name}"
        summary = summaries.get(name, "")
        text = f"{'#' * level} `{command}`\n\n"
        if summary:
            text += f"{summary[0].upper()}{summary[1:]}.\n\n"
        text += f"```text\n{sub.format_help().rstrip()}\n```\n"
        sections.append(text)
        sections.extend(command_sections(sub, command, level + 1))
    return sections


def command_reference() -> str:
    from longtime.commands.cli import build_parser

    previous = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    try:
        parser = build_parser()
        parser.prog = "longtime"
        return "\n".join(command_sections(parser))
    finally:
        if previous is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = previous


def on_page_markdown(markdown: str, page, config, files) -> str:
    if MARKER not in markdown:
        return markdown
    return markdown.replace(MARKER, command_reference())
