"""The problem files shipped with optik (TOML), installed as the package ``optik.problems``."""
