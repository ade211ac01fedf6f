from loopworks.cli import main

main()
