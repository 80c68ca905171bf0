"""processing: the field coverage check and the hand-off to reconstruction."""
