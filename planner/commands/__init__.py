"""One module per ``compplan`` sub-command; each defines ``register(subparsers)``."""
