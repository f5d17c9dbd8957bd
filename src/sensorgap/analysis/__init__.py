"""Analyses built on the coverage engine: near field (blind spots, Fig. 5), far field
(Table IV) and the paper's results section."""
