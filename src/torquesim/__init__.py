"""torquesim"""
