"""Detection on the user's own recordings: reading and checking files, derivatives from real sampling, the trust
checks around the λ-sweep, and the ``nnphd detect`` pipeline with its report."""
