"""The seed's time discretisation: the three-level theta-scheme and its modal (block-diagonal) form; its stability is
:mod:`ebb_model.stability`'s."""
