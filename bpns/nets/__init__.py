"""Small networks the skills and the baselines are built from: torch and numpy layers,
standardisation and Adam (:mod:`bpns.nets.layers`), fully-connected regressors, Gaussians
and classifiers with their config (:mod:`bpns.nets.mlp`), and the ridge-regression base
under them (:mod:`bpns.nets.linear`)."""
