"""The paper's experiments (Table II and Fig. 3, Fig. 4, Fig. 5, Fig. 6, the reproduction report), on the engine."""
