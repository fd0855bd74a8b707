"""The bank's FOURTH TEST HALF: ten more truths of the same geared servo pendulum, written from
literature without reading the discrepancy library, in forms none of the three earlier halves
used, to be run once after the method's rules freeze (bank/README.md, "The fourth test
half")."""
