"""Planning methods: local laws, Bellman DP, NLP, TOPP-RA, Ruckig. Each returns a Trajectory."""
