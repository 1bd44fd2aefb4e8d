"""Agent evaluations (issue 41): people judge what trained agents do, head to head."""
