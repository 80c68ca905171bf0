"""How large a plan sfap makes unless told otherwise. Standard library only: ``sfap plan`` shows
these as its defaults before it imports the planner (numpy, shapely, pyproj), which it does only
once map.png's helper process is started (sfap/commands/plan.py)."""

#: The most photos a plan is made for unless asked for more (sfap plan --max-photos): about
#: 570 MB of memory and 15-90 s of planning, quiet machine to loaded (BENCHMARKS.md, "The
#: planner's size"); the 1,000 km2 block at 2.4 cm (about 957,000 photos) is refused.
MAX_PHOTOS = 500_000
#: A plan estimated above this many photos takes more than a few seconds: the command says so.
ANNOUNCE_PHOTOS = 20_000
