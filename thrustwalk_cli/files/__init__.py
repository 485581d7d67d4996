"""Every file format: YAML in (safe loader, restricted expressions, schemas), JSON/CSV/figures
out (atomic writes, provenance); no model mathematics."""
