from setuptools import find_packages, setup

package_name = 'wallbot_example_controller'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='wallbot_sim maintainers',
    maintainer_email='wallbot-sim@example.com',
    description='An outside controller for the wallbot, tested against wallbot_sim.',
    license='Apache-2.0',
    extras_require={'test': ['pytest', 'wallbot_sim[ros]']},
    entry_points={
        'console_scripts': ['example_controller = wallbot_example_controller.node:main'],
    },
)
