"""Running skills in the exact simulator, and what a run leaves: rollout records, failure
reasons, videos."""
