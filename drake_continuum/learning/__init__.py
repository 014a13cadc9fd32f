"""Classification: reading wrap collections, the sklearn pipeline, evaluation over random
splits and the portable model file; accuracy on placed copies (placements)."""
