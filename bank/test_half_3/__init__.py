"""The bank's THIRD TEST HALF: ten more truths of the same geared servo pendulum, written from
literature without reading the discrepancy library, in other forms than the first and second
halves', to be run once after the method's rules freeze (bank/README.md, "The third test
half")."""
