"""Studies over many trainings: their plans, claim checks and reports (Table 2, physics)."""
