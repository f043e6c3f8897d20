"""plant_models"""
