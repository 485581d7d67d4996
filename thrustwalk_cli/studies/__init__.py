"""Studies: one module per command, options -> a result object that renders itself (JSON
document, CSV tables, figures). Writes no file; imports no typer, rich or matplotlib (figures
are drawn by :mod:`thrustwalk_cli.plots`, imported when asked for)."""
