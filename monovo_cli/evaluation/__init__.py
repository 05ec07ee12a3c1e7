"""A trajectory against ground truth: pairing by time (:mod:`.sync`), the error measures
(:mod:`.metrics`) and their text tables (:mod:`.report`). Arrays in, numbers out."""
