from ivslam_cli.cli import main

main()
