"""Plants the campaign digs with, each implementing `plant_models.plant.Plant`: the simulated
excavator (FMUs under the co-simulation master, the arm coupling and the servo)."""
