"""``downhole design ...``: controller synthesis commands (EID, DHP) live on this sub-app."""

from __future__ import annotations

import typer

from downhole.cli import app

design_app = typer.Typer(no_args_is_help=True, help="Design (synthesize/train) a controller.")
app.add_typer(design_app, name="design")
