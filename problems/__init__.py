"""Problems built on a model: compensation, paths, (later) posture NLP and identification,
and the problem files shipped as data.  Depends on :mod:`models` only."""
