"""A trajectory against ground truth: pairing by time or frame (:mod:`.sync`), the error
measures (:mod:`.metrics`, by distance :mod:`.segments`, all at once :mod:`.drive`) and their
text (:mod:`.report`). Arrays in, numbers out."""
