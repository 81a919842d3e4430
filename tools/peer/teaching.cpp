// The race's "teaching" peer: ContinuumRobotExamples' RK4 shooting with its
// Levenberg-Marquardt (ode4, solveLevenbergMarquardt, as published; its
// Library folder on the include path) on a cantilever with a tip force.
// Prints, for each number of points N (N - 1 elements), the median time of
// a solve [us] and the node positions. Built and run by tools/peer_race.py.
#include <iostream>
#include <chrono>
#include <vector>
#include <algorithm>
#include <commonmath.h>
#include <numericalintegration.h>
#include <convexoptimization.h>
using namespace ContinuumRobotLibrary;

static double ALPHA = 3.0;
const double L = 1.0;
const DiagonalMatrix<double, 3> Kse(1e10, 1e10, 1e10);  // stiff: inextensible, unshearable
const DiagonalMatrix<double, 3> Kbt(1.0, 1.0, 1.0);

VectorXd ode(VectorXd y){
    Matrix3d R = Map<Matrix3d>(y.segment<9>(3).data());
    Vector3d n = y.segment<3>(12);
    Vector3d m = y.segment<3>(15);
    Vector3d v = Kse.inverse()*R.transpose()*n + Vector3d::UnitZ();
    Vector3d u = Kbt.inverse()*R.transpose()*m;
    Vector3d p_s = R*v;
    Matrix3d R_s = R*hat(u);
    Vector3d n_s = Vector3d::Zero();
    Vector3d m_s = -p_s.cross(n);
    VectorXd y_s(18);
    y_s << p_s, Map<VectorXd>(R_s.data(), 9), n_s, m_s;
    return y_s;
}

template<int N>
struct Shoot {
    static MatrixXd Y;
    static VectorXd f(VectorXd guess){
        VectorXd y0(18);
        y0 << Vector3d::Zero(), Map<VectorXd>(Matrix3d(Matrix3d::Identity()).data(), 9), guess;
        Y = ode4<ode, N>(y0, L);
        Vector3d nL = Y.block<3,1>(12, Y.cols()-1);
        Vector3d mL = Y.block<3,1>(15, Y.cols()-1);
        Vector6d e;
        e << nL - Vector3d(0, -ALPHA, 0), mL;
        return e;
    }
};
template<int N> MatrixXd Shoot<N>::Y;

template<int N>
void run(double tol){
    VectorXd sol;
    std::vector<double> times;
    for(int k = 0; k < 400; k++){
        auto t0 = std::chrono::steady_clock::now();
        try { sol = solveLevenbergMarquardt<Shoot<N>::f>(VectorXd::Zero(6), tol); }
        catch (...) { std::cout << N << " nan\n"; return; }
        auto t1 = std::chrono::steady_clock::now();
        times.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    }
    std::sort(times.begin(), times.end());
    Shoot<N>::f(sol);
    std::cout << N << " " << times[times.size()/2];
    for(int j = 0; j < Shoot<N>::Y.cols(); j++)
        std::cout << " " << Shoot<N>::Y(0,j) << " " << Shoot<N>::Y(1,j) << " " << Shoot<N>::Y(2,j);
    std::cout << "\n";
}

int main(int argc, char** argv){
    ALPHA = atof(argv[1]);
    double tol = argc > 2 ? atof(argv[2]) : 1e-12;
    std::cout.precision(17);
    run<5>(tol); run<6>(tol); run<9>(tol); run<11>(tol); run<17>(tol); run<21>(tol); run<33>(tol); run<41>(tol); run<65>(tol); run<81>(tol); run<129>(tol);
}
